#!/usr/bin/env python3
"""Whole-process folder comparison: `ferrocal detect` against OpenCV on the same image files.

Two sets, each timed as a user would run it (process start, reading the files, detection,
writing the results; wall time of the whole process):

- chessboards: the real-like renders (`vision/tests/support/reallike.rs`, written to a folder
  by `realistic write`; 8 views 2.3-5 MP, 418-570 inner corners, PNG and JPEG, truth beside
  each image), `ferrocal detect` once per board size against one Python process running
  OpenCV's findChessboardCornersSB (NORMALIZE_IMAGE | EXHAUSTIVE, as the Rust baseline) on
  every file;
- ChArUco: the 16 real 1600x1200 images of the ROS-Industrial industrial_calibration example
  data (`test_set_charuco/images`), `ferrocal detect --pattern charuco:...` against one Python
  process running OpenCV's CharucoDetector.detectBoard (default parameters).

The runs alternate (ferrocal, OpenCV, ferrocal, ...); the medians are printed side by side with
the boards found, the corners found and, per image, ferrocal's own stage times (`--timings`)
and OpenCV's per-image time measured inside its process.

    python3 scripts/detect_folder_vs_opencv.py [--runs 3] [--threads 1] [--folder DIR]
        [--skip-chessboards | --skip-charuco] [--ferrocal PATH]

`--threads N` limits both sides (`ferrocal detect --threads N`, which detects N images at a
time and limits OpenCV inside ferrocal to N threads; cv2.setNumThreads for the OpenCV process,
which detects one image after the other and parallelises inside each); without it both use
every core. Needs the release binaries
(`cargo build --release --offline -p ferrocal` and
`cargo build --release --offline -p ferrocal-vision --example realistic`) and
opencv-python-headless.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CHARUCO_DIR = os.path.join(ROOT, "..", "shared", "data", "industrial_calibration", "test_set_charuco", "images")
CHARUCO_PATTERN = "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250"
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg")


def opencv_worker(kind, threads, files):
    """Runs inside the OpenCV process: detects in every file, prints one JSON line."""
    import cv2  # imported here: its import time belongs to the timed process

    if threads:
        cv2.setNumThreads(threads)
    out = []
    if kind == "charuco":
        _, size, square_mm, marker_mm, dictionary = CHARUCO_PATTERN.split(":")
        cols, rows = (int(v) for v in size.split("x"))
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
        board = cv2.aruco.CharucoBoard((cols, rows), float(square_mm[:-2]) * 1e-3, float(marker_mm[:-2]) * 1e-3, d)
        det = cv2.aruco.CharucoDetector(board)
    for f in files:
        t0 = time.perf_counter()
        img = cv2.imread(f["path"], cv2.IMREAD_GRAYSCALE)
        if kind == "charuco":
            corners, _, _, _ = det.detectBoard(img)
            n = 0 if corners is None else len(corners)
        else:
            flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE
            ok, corners = cv2.findChessboardCornersSB(img, (f["cols"], f["rows"]), flags=flags)
            n = len(corners) if ok else 0
        out.append({"path": f["path"], "corners": n, "ms": (time.perf_counter() - t0) * 1e3})
    print(json.dumps(out))


def run_opencv(kind, files, threads):
    """One OpenCV process over `files`: wall time in ms and its per-file results."""
    spec = json.dumps({"kind": kind, "threads": threads, "files": files})
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, __file__, "--opencv-worker"], input=spec, capture_output=True, text=True)
    wall_ms = (time.perf_counter() - t0) * 1e3
    if p.returncode != 0:
        sys.exit(f"OpenCV worker failed: {p.stderr}")
    return wall_ms, json.loads(p.stdout.strip().splitlines()[-1])


def run_ferrocal(ferrocal, groups, threads, tmp):
    """`ferrocal detect --timings` once per pattern group: summed wall time in ms and the JSON
    entries of every image."""
    env = dict(os.environ)
    if threads:
        env["RAYON_NUM_THREADS"] = str(threads)
    total_ms, entries = 0.0, []
    for k, (pattern, paths) in enumerate(sorted(groups.items())):
        out = os.path.join(tmp, f"ferrocal_{k}.json")
        cmd = [ferrocal, "detect", "--images", *paths, "--pattern", pattern, "--json", out, "--timings"]
        if threads:
            cmd += ["--threads", str(threads)]
        t0 = time.perf_counter()
        p = subprocess.run(cmd, env=env, capture_output=True, text=True)
        total_ms += (time.perf_counter() - t0) * 1e3
        if p.returncode not in (0, 2):
            sys.exit(f"{' '.join(cmd)} failed ({p.returncode}): {p.stderr}")
        with open(out) as f:
            entries.extend(json.load(f))
    return total_ms, entries


def corners_of(entry):
    return sum(len(d["corners_px"]) for d in entry.get("detections", []))


def compare(title, kind, groups, files, ferrocal, runs, threads, tmp):
    ours, theirs = [], []
    last_ours = last_cv = None
    for _ in range(runs):
        ms, last_ours = run_ferrocal(ferrocal, groups, threads, tmp)
        ours.append(ms)
        ms, last_cv = run_opencv(kind, files, threads)
        theirs.append(ms)
    mo, mc = statistics.median(ours), statistics.median(theirs)
    by_path = {e["image"]: e for e in last_ours}
    print(f"\n### {title}\n")
    print(f"{len(files)} images, {runs} alternating runs, median whole-process wall time; threads: "
          f"{threads if threads else 'every core'} each\n")
    print("| image | ferrocal corners | OpenCV corners | ferrocal read + detect ms (--timings) | OpenCV read + detect ms |")
    print("|---|---|---|---|---|")
    found_ours = found_cv = corners_ours = corners_cv = 0
    for f, cv in zip(files, last_cv):
        e = by_path.get(f["path"], {})
        n = corners_of(e) if not e.get("error") else 0
        t = e.get("timings") or {}
        found_ours += n > 0
        found_cv += cv["corners"] > 0
        corners_ours += n
        corners_cv += cv["corners"]
        ms = t.get("read_ms", 0.0) + t.get("total_ms", 0.0)
        print(f"| {os.path.basename(f['path'])} | {n} | {cv['corners']} | {ms:.0f} | {cv['ms']:.0f} |")
    print(f"\n| process | median wall ms (runs) | ratio | images found | corners |")
    print("|---|---|---|---|---|")
    print(f"| ferrocal detect | {mo:.0f} ({', '.join(f'{v:.0f}' for v in ours)}) | {mo / mc:.2f} | "
          f"{found_ours}/{len(files)} | {corners_ours} |")
    print(f"| OpenCV ({'CharucoDetector.detectBoard' if kind == 'charuco' else 'findChessboardCornersSB'}, python) | "
          f"{mc:.0f} ({', '.join(f'{v:.0f}' for v in theirs)}) | 1.00 | {found_cv}/{len(files)} | {corners_cv} |")


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--opencv-worker":
        spec = json.load(sys.stdin)
        opencv_worker(spec["kind"], spec["threads"], spec["files"])
        return
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="alternating runs per side (median)")
    ap.add_argument("--threads", type=int, default=0, help="threads per side (0: every core)")
    ap.add_argument("--folder", default=os.path.join(ROOT, "target", "reallike_folder"),
                    help="where the real-like renders are written (rewritten when it has no images)")
    ap.add_argument("--ferrocal", default=os.path.join(ROOT, "target", "release", "ferrocal"))
    ap.add_argument("--realistic", default=os.path.join(ROOT, "target", "release", "examples", "realistic"))
    ap.add_argument("--skip-charuco", action="store_true")
    ap.add_argument("--skip-chessboards", action="store_true", help="only the ChArUco set")
    args = ap.parse_args()
    for exe in (args.ferrocal, args.realistic):
        if not os.path.exists(exe):
            sys.exit(f"{exe} is missing: build the release binaries first (see the docstring)")
    names = sorted(n for n in os.listdir(args.folder)) if os.path.isdir(args.folder) else []
    if args.skip_chessboards:
        names = []
    elif not any(n.endswith(IMAGE_EXTENSIONS) for n in names):
        subprocess.run([args.realistic, "write", args.folder], check=True)
        names = sorted(os.listdir(args.folder))
    groups, files = {}, []
    for n in names:
        if not n.endswith(IMAGE_EXTENSIONS):
            continue
        path = os.path.join(args.folder, n)
        with open(os.path.join(args.folder, os.path.splitext(n)[0] + ".truth.json")) as f:
            pattern = json.load(f)["pattern"]
        cols, rows = (int(v) for v in pattern.split(":")[1].split("x"))
        groups.setdefault(pattern, []).append(path)
        files.append({"path": path, "cols": cols, "rows": rows})
    with tempfile.TemporaryDirectory() as tmp:
        if not args.skip_chessboards:
            compare(f"Chessboards, real-like renders ({args.folder})", "chessboard", groups, files, args.ferrocal,
                    args.runs, args.threads, tmp)
        if not args.skip_charuco:
            paths = sorted((os.path.join(CHARUCO_DIR, n) for n in os.listdir(CHARUCO_DIR) if n.endswith(".png")),
                           key=lambda p: int(os.path.splitext(os.path.basename(p))[0]))
            compare("ChArUco 5x7, 16 real 1600x1200 images (industrial_calibration test_set_charuco)", "charuco",
                    {CHARUCO_PATTERN: paths}, [{"path": p} for p in paths], args.ferrocal, args.runs, args.threads,
                    tmp)


if __name__ == "__main__":
    main()
