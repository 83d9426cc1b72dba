#!/usr/bin/env python3
"""ferrocal handeye beside its peers on the same corners and split (issue #32, item 4).

A development baseline, never a dependency of the product (not in CI, not in scripts/setup.sh).
Dependencies (Python 3.10+):

    pip install opencv-python-headless numpy vision-calibration==0.9.0

For each shared real hand-eye set (ROS-Industrial industrial_calibration example data,
Apache-2.0; ../shared/data/industrial_calibration, read in place, never copied):

1. `ferrocal import ic-handeye --test-every 2` writes the poses table (every second image,
   natural order, held out: `split` = test), then `ferrocal handeye ... --json --corners-out`
   runs ferrocal and exports the exact corners it used (point ids, pixels), the nominal target
   points, the robot poses and the split.
2. On those corners and that split:
   - OpenCV: cv2.calibrateCamera on the training views (default flags: k1 k2 p1 p2 k3, the
     model of ferrocal's default `brown5`), cv2.solvePnP per training view, then
     cv2.calibrateHandEye (TSAI, PARK, HORAUD, ANDREFF, DANIILIDIS) and
     cv2.calibrateRobotWorldHandEye (SHAH, LI). For calibrateHandEye the other transform is the
     mean over the training views of what each implies (chordal mean of the rotations, mean of
     the translations), as ferrocal's own OpenCV comparison does (calib/src/handeye/opencv.rs);
     for eye-to-hand the robot poses are inverted, as OpenCV documents.
   - vision-calibration 0.9 (`run_single_cam_handeye`) on the training views, with and without
     its robot-pose refinement (its defaults otherwise: Brown-Conrady with k3 fixed), and each
     again with `intrinsics.fix_k3 = False` (closer to ferrocal's and OpenCV's model). With its
     refinement the training views' robot poses are corrected inside its fit; every figure here
     still uses the poses as reported (a held-out view has no corrected pose). With the poses
     exact the script checks that its mean error reproduces vision-calibration's own
     `mean_reproj_error`, which confirms how its transforms are read.
   - ferrocal itself: its default (robot poses exact, print scale fitted) and with the nominal
     target scale (`--nominal-target-scale`, the geometry every peer uses).
3. Every row's figures come from one function here (`chain_rms`): every corner of a view
   predicted through T_base_flange as reported, X, W (and ferrocal's print scale) and the
   method's own camera, minus the detected corner; RMS of the 2D error length over the training
   corners and over the held-out (test) corners. Test views take no part in any fit. The script
   checks that this function reproduces ferrocal's own train and held-out figures.

Usage:
    python3 scripts/handeye_peers.py [--ferrocal target/debug/ferrocal] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

ATTRIBUTION = "ROS-Industrial industrial_calibration example data, Apache-2.0"
SETS = ["test_set_10x10", "test_set_charuco"]
REPO = Path(__file__).resolve().parent.parent


# --------------------------------------------------------------------------------------------
# Rigid transforms as 4x4 matrices (T_a_b maps frame-b coordinates into frame a).


def T(R, t):
    m = np.eye(4)
    m[:3, :3] = np.asarray(R, float)
    m[:3, 3] = np.asarray(t, float).reshape(3)
    return m


def inv(m):
    R, t = m[:3, :3], m[:3, 3]
    return T(R.T, -R.T @ t)


def quat_wxyz_to_R(q):
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def R_to_quat_xyzw(R):
    q = np.empty(4)
    tr = np.trace(R)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, 0.25 * s]
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + R[i, i] - R[j, j] - R[k, k])
        v = np.zeros(3)
        v[i] = 0.25 * s
        v[j] = (R[j, i] + R[i, j]) / s
        v[k] = (R[k, i] + R[i, k]) / s
        q = [v[0], v[1], v[2], (R[k, j] - R[j, k]) / s]
    q = np.asarray(q)
    return q / np.linalg.norm(q)


def xyzw_to_R(q):
    x, y, z, w = q
    return quat_wxyz_to_R([w, x, y, z])


def ferrocal_T(t):
    """`{"translation_mm", "rotation_wxyz"}` of ferrocal's JSON, as a 4x4 in metres."""
    return T(quat_wxyz_to_R(t["rotation_wxyz"]), np.asarray(t["translation_mm"]) * 1e-3)


def project_so3(m):
    u, _, vt = np.linalg.svd(m)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def average_transforms(ts):
    """Chordal mean of the rotations, mean of the translations (ferrocal's average_transforms)."""
    r = project_so3(sum(t[:3, :3] for t in ts))
    return T(r, np.mean([t[:3, 3] for t in ts], axis=0))


# --------------------------------------------------------------------------------------------
# The one metric.


def t_camera_target(mount, X, W, t_base_flange):
    if mount == "eye-in-hand":  # X = T_flange_camera, W = T_base_target
        return inv(X) @ inv(t_base_flange) @ W
    return inv(W) @ t_base_flange @ X  # X = T_flange_target, W = T_base_camera


def chain_rms(data, camera, X, W, scale=1.0):
    """(train RMS px, held-out RMS px, unprojected corners) of the chain, robot poses as reported.

    `camera` = (K 3x3, OpenCV distortion vector). A corner behind the camera counts as missing,
    as in ferrocal (calib/src/handeye/evaluate.rs)."""
    K, dist = camera
    sums = {"train": [0.0, 0], "test": [0.0, 0]}
    missing = 0
    pts = data["target"] * scale
    for v in data["views"]:
        t = t_camera_target(data["mount"], X, W, v["t_base_flange"])
        p = pts[v["ids"]]
        pc = (t[:3, :3] @ p.T).T + t[:3, 3]
        front = pc[:, 2] > 0
        missing += int((~front).sum())
        if not front.any():
            continue
        rvec, _ = cv2.Rodrigues(t[:3, :3])
        proj, _ = cv2.projectPoints(p[front], rvec, t[:3, 3], K, dist)
        e = proj.reshape(-1, 2) - v["px"][front]
        s = sums[v["split"]]
        s[0] += float((e**2).sum())
        s[1] += len(e)
    rms = lambda s: float(np.sqrt(s[0] / s[1])) if s[1] else float("nan")  # noqa: E731
    return rms(sums["train"]), rms(sums["test"]), missing


# --------------------------------------------------------------------------------------------
# ferrocal


def run(cmd):
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(map(str, cmd))}\n{r.stdout}\n{r.stderr}")
    return r.stdout


def ferrocal_runs(binary, set_dir, tmp, name):
    poses = tmp / f"{name}.csv"
    run([binary, "import", "ic-handeye", "--test-every", "2", "--input", set_dir, "--out", poses])
    meta = {}
    for line in poses.read_text().splitlines():
        if line.startswith("# ") and ": " in line:
            k, v = line[2:].split(": ", 1)
            meta[k] = v
    base = [binary, "handeye", "--images", set_dir / "images", "--poses", poses,
            "--pattern", meta["pattern"], "--mount", meta["mount"]]
    res, corners, nominal = tmp / f"{name}.json", tmp / f"{name}.corners.json", tmp / f"{name}.nominal.json"
    cmd = base + ["--json", res, "--corners-out", corners]
    run(cmd)
    run(base + ["--nominal-target-scale", "--no-physics", "--json", nominal])
    shown = " ".join(str(c) for c in cmd).replace(str(tmp), "$TMP").replace(str(REPO) + "/", "")
    return json.loads(res.read_text()), json.loads(nominal.read_text()), json.loads(corners.read_text()), shown


def load_corners(c):
    views = []
    for v in c["views"]:
        if not v["used"]:
            continue
        views.append({
            "name": v["image"],
            "split": v["split"],
            "t_base_flange": ferrocal_T(v["t_base_flange"]),
            "ids": np.asarray(v["point_ids"], int),
            "px": np.asarray(v["corners_px"], float),
            "size": tuple(v["image_size"]),
        })
    # ferrocal's chain predicts through the target as it fitted it (bent and printed as found on
    # the training images, `handeye`'s physics); the peers take the nominal target.
    chain_target = np.asarray(c.get("chain_target_points_m", c["target_points_m"]), float)
    return {"mount": c["mount"], "pattern": c["pattern"], "target": np.asarray(c["target_points_m"], float),
            "chain_target": chain_target, "views": views, "source": c.get("data_source")}


def ferrocal_camera(r):
    k = r["camera"]
    assert k["model"] in ("brown5", "rational8"), k["model"]  # OpenCV's order either way
    K = np.array([[k["fx"], 0, k["cx"]], [0, k["fy"], k["cy"]], [0, 0, 1.0]])
    return K, np.asarray(k["distortion"], float)  # k1 k2 p1 p2 k3, OpenCV's order


def ferrocal_row(label, r, data):
    scale = r["target_scale"]["value"] if r.get("target_scale") else 1.0
    X, W = ferrocal_T(r["hand_eye"]), ferrocal_T(r["world"])
    train, held, missing = chain_rms(dict(data, target=data["chain_target"]), ferrocal_camera(r), X, W, scale)
    # The script's metric must be ferrocal's own.
    for mine, theirs in [(train, r["train_rms_px"]), (held, r["heldout_rms_px"])]:
        if abs(mine - theirs) > 1e-6:
            sys.exit(f"{label}: this script's chain RMS {mine} differs from ferrocal's {theirs}")
    return {"method": label, "heldout_rms_px": held, "train_rms_px": train, "unprojected": missing,
            "note": f"print scale {scale:.5f}" if scale != 1.0 else "nominal target scale"}


# --------------------------------------------------------------------------------------------
# OpenCV


def opencv_fits(data):
    """OpenCV's hand-eye fits on the training views: (label, X, W, (K, dist), note) per method."""
    train = [v for v in data["views"] if v["split"] == "train"]
    obj = [data["target"][v["ids"]].astype(np.float32) for v in train]
    img = [v["px"].astype(np.float32).reshape(-1, 1, 2) for v in train]
    size = train[0]["size"]
    rms, K, dist, _, _ = cv2.calibrateCamera(obj, img, size, None, None)
    dist = dist.reshape(-1)
    cam_target = []
    for v in train:
        ok, rvec, tvec = cv2.solvePnP(data["target"][v["ids"]], v["px"], K, dist)
        assert ok, v["name"]
        cam_target.append(T(cv2.Rodrigues(rvec)[0], tvec))
    flange = [v["t_base_flange"] for v in train]
    eih = data["mount"] == "eye-in-hand"
    fits = []
    camera_note = f"cv2.calibrateCamera on the training views: RMS {rms:.3f} px, fx {K[0, 0]:.1f}, fy {K[1, 1]:.1f}"

    def add(function, method, X, W):
        fits.append((f"OpenCV {function} {method}", X, W, (K, dist), camera_note))

    robot = flange if eih else [inv(f) for f in flange]
    for method in ["TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS"]:
        R, t = cv2.calibrateHandEye([m[:3, :3] for m in robot], [m[:3, 3].reshape(3, 1) for m in robot],
                                    [m[:3, :3] for m in cam_target], [m[:3, 3].reshape(3, 1) for m in cam_target],
                                    method=getattr(cv2, f"CALIB_HAND_EYE_{method}"))
        out = T(project_so3(R), t)
        if eih:  # out = T_flange_camera; W_i = T_base_flange X T_camera_target
            X = out
            W = average_transforms([f @ X @ c for f, c in zip(flange, cam_target)])
        else:  # out = T_base_camera; X_i = T_base_flange^-1 W T_camera_target
            W = out
            X = average_transforms([inv(f) @ W @ c for f, c in zip(flange, cam_target)])
        add("calibrateHandEye", method, X, W)
    # T_cam_world T_world_base = T_cam_gripper T_gripper_base, world = the target.
    robot = [inv(f) for f in flange] if eih else flange
    for method in ["SHAH", "LI"]:
        r1, t1, r2, t2 = cv2.calibrateRobotWorldHandEye(
            [m[:3, :3] for m in cam_target], [m[:3, 3].reshape(3, 1) for m in cam_target],
            [m[:3, :3] for m in robot], [m[:3, 3].reshape(3, 1) for m in robot],
            method=getattr(cv2, f"CALIB_ROBOT_WORLD_HAND_EYE_{method}"))
        base2world, gripper2cam = T(project_so3(r1), t1), T(project_so3(r2), t2)
        # eye-in-hand: base2world = T_target_base, gripper2cam = T_camera_flange;
        # eye-to-hand: base2world = T_target_flange, gripper2cam = T_camera_base.
        X, W = (inv(gripper2cam), inv(base2world)) if eih else (inv(base2world), inv(gripper2cam))
        add("calibrateRobotWorldHandEye", method, X, W)
    return fits


def opencv_rows(data):
    rows = []
    for label, X, W, camera, note in opencv_fits(data):
        tr, held, missing = chain_rms(data, camera, X, W)
        rows.append({"method": label, "heldout_rms_px": held, "train_rms_px": tr, "unprojected": missing,
                     "note": note})
    return rows


# --------------------------------------------------------------------------------------------
# vision-calibration


def vc_pose(m):
    import vision_calibration as vc

    return vc.Pose(rotation_xyzw=tuple(R_to_quat_xyzw(m[:3, :3])), translation_xyz=tuple(m[:3, 3]))


def vc_T(p):
    return T(xyzw_to_R(p.rotation_xyzw), p.translation_xyz)


VC_VARIANTS = [(False, True), (True, True), (False, False), (True, False)]  # (refine poses, fix_k3)


def vc_single_fits(data, variants=VC_VARIANTS):
    """vision-calibration's run_single_cam_handeye on the training views, per (refine, fix_k3):
    (label, X, W, (K, dist), result, refine) or (label, None, None, None, error message, refine)."""
    import vision_calibration as vc

    train = [v for v in data["views"] if v["split"] == "train"]
    dataset = vc.SingleCamHandeyeDataset(views=[
        vc.SingleCamHandeyeView(
            observation=vc.Observation(points_3d=[tuple(p) for p in data["target"][v["ids"]]],
                                       points_2d=[tuple(p) for p in v["px"]]),
            base_se3_gripper=vc_pose(v["t_base_flange"]))
        for v in train
    ])
    eih = data["mount"] == "eye-in-hand"
    fits = []
    for refine, fix_k3 in variants:
        cfg = vc.SingleCamHandeyeCalibrationConfig()
        cfg.handeye_init.handeye_mode = "EyeInHand" if eih else "EyeToHand"
        cfg.robot_poses.refine = refine
        cfg.intrinsics.fix_k3 = fix_k3
        label = (f"vision-calibration {vc.__version__} run_single_cam_handeye, "
                 f"robot poses {'refined' if refine else 'exact'}{'' if fix_k3 else ', intrinsics.fix_k3=False'}")
        try:
            res = vc.run_single_cam_handeye(dataset, cfg)
        except Exception as e:  # noqa: BLE001 - report the peer's failure as a row
            fits.append((label, None, None, None, str(e), refine))
            continue
        k, d = res.camera.intrinsics, res.camera.distortion
        K = np.array([[k.fx, k.skew, k.cx], [0, k.fy, k.cy], [0, 0, 1.0]])
        dist = np.array([d.k1, d.k2, d.p1, d.p2, d.k3])
        # gripper_se3_camera is T_gripper_camera (maps camera coordinates to the gripper),
        # base_se3_target T_base_target; camera_se3_base T_camera_base, gripper_se3_target
        # T_gripper_target. Checked in vc_rows against vision-calibration's own mean error.
        if eih:
            X, W = vc_T(res.gripper_se3_camera), vc_T(res.base_se3_target)
        else:
            X, W = vc_T(res.gripper_se3_target), inv(vc_T(res.camera_se3_base))
        fits.append((label, X, W, (K, dist), res, refine))
    return fits


def vc_rows(data):
    rows = []
    for label, X, W, camera, res, refine in vc_single_fits(data):
        if X is None:
            rows.append({"method": label, "heldout_rms_px": None, "train_rms_px": None, "error": res})
            continue
        k = res.camera.intrinsics
        tr, held, missing = chain_rms(data, camera, X, W)
        mean = mean_error(data, camera, X, W)
        if not refine and abs(mean - res.mean_reproj_error) > 1e-3:
            # With the poses exact, its own figure must be ours: the frames are read right.
            sys.exit(f"{label}: mean error {mean} px here against its own {res.mean_reproj_error} px")
        rows.append({"method": label, "heldout_rms_px": held, "train_rms_px": tr, "unprojected": missing,
                     "note": f"its own mean reprojection error {res.mean_reproj_error:.3f} px "
                             f"(this script, robot poses as reported: {mean:.3f} px); "
                             f"fx {k.fx:.1f}, fy {k.fy:.1f}, skew {k.skew:.3g}"})
    return rows


def mean_error(data, camera, X, W):
    """Mean (not RMS) 2D error over the training corners: vision-calibration's own measure."""
    K, dist = camera
    errs = []
    for v in data["views"]:
        if v["split"] != "train":
            continue
        t = t_camera_target(data["mount"], X, W, v["t_base_flange"])
        rvec, _ = cv2.Rodrigues(t[:3, :3])
        proj, _ = cv2.projectPoints(data["target"][v["ids"]], rvec, t[:3, 3], K, dist)
        errs.extend(np.linalg.norm(proj.reshape(-1, 2) - v["px"], axis=1))
    return float(np.mean(errs))


# --------------------------------------------------------------------------------------------


def fmt(x):
    return "-" if x is None or (isinstance(x, float) and np.isnan(x)) else f"{x:.3f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    default_bin = next((p for p in [REPO / "target/release/ferrocal", REPO / "target/debug/ferrocal"] if p.exists()),
                       REPO / "target/release/ferrocal")
    ap.add_argument("--ferrocal", type=Path, default=default_bin, help="the ferrocal binary")
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared/data/industrial_calibration",
                    help="the industrial_calibration folder (read in place)")
    ap.add_argument("--sets", nargs="+", default=SETS)
    ap.add_argument("--out", type=Path, help="write handeye_peers.json and handeye_peers.md here")
    a = ap.parse_args()
    if not a.data.is_dir():
        a.data = Path("/work/shared/data/industrial_calibration")
    import vision_calibration as vc

    report = {"data_source": ATTRIBUTION, "ferrocal": str(a.ferrocal), "opencv": cv2.__version__,
              "vision_calibration": vc.__version__, "sets": {}}
    md = [f"# ferrocal handeye beside OpenCV and vision-calibration\n",
          f"Data: {ATTRIBUTION} (`industrial_calibration/<set>`), every second image held out.",
          f"OpenCV {cv2.__version__}, vision-calibration {vc.__version__}. Chain RMS in pixels, robot poses "
          "as reported; held-out images take no part in any fit.\n"]
    with tempfile.TemporaryDirectory() as tmpd:
        tmp = Path(tmpd)
        for name in a.sets:
            r, r_nom, c, cmd = ferrocal_runs(a.ferrocal.resolve(), a.data / name, tmp, name)
            data = load_corners(c)
            n_train = sum(v["split"] == "train" for v in data["views"])
            rows = [ferrocal_row("ferrocal handeye (default: poses exact, print scale fitted)", r, data),
                    ferrocal_row("ferrocal handeye --nominal-target-scale --no-physics", r_nom, data)]
            rows += opencv_rows(data)
            rows += vc_rows(data)
            ours = rows[0]["heldout_rms_px"]
            best = lambda prefix: min((x for x in rows if x["method"].startswith(prefix) and x["heldout_rms_px"] is not None),  # noqa: E731
                                      key=lambda x: x["heldout_rms_px"])
            b_cv, b_vc = best("OpenCV"), best("vision-calibration")
            verdict = {
                "ferrocal_heldout_rms_px": ours,
                "opencv_best": b_cv["method"], "opencv_best_heldout_rms_px": b_cv["heldout_rms_px"],
                "vision_calibration_best": b_vc["method"],
                "vision_calibration_best_heldout_rms_px": b_vc["heldout_rms_px"],
                "below_both": ours < b_cv["heldout_rms_px"] and ours < b_vc["heldout_rms_px"],
            }
            report["sets"][name] = {"mount": data["mount"], "pattern": data["pattern"], "ferrocal_command": cmd,
                                    "views": len(data["views"]), "train_views": n_train,
                                    "test_views": len(data["views"]) - n_train, "rows": rows, "must_hold": verdict}
            head = (f"{name} ({data['mount']}, {data['pattern']}; {n_train} training, "
                    f"{len(data['views']) - n_train} held-out images)")
            print(f"\n{head}\n  ferrocal: {cmd}")
            print(f"  {'method':<88} {'held-out px':>11} {'train px':>9}")
            md += [f"## {head}\n", f"`{cmd}`\n", "| method | held-out chain RMS px | training chain RMS px | note |",
                   "| --- | --- | --- | --- |"]
            for x in rows:
                print(f"  {x['method']:<88} {fmt(x['heldout_rms_px']):>11} {fmt(x['train_rms_px']):>9}")
                md.append(f"| {x['method']} | {fmt(x['heldout_rms_px'])} | {fmt(x['train_rms_px'])} | "
                          f"{x.get('note') or x.get('error', '')} |")
            line = (f"ferrocal {fmt(ours)} px held out; OpenCV best {fmt(b_cv['heldout_rms_px'])} px "
                    f"({b_cv['method']}); vision-calibration best {fmt(b_vc['heldout_rms_px'])} px "
                    f"({b_vc['method']}): ferrocal below both: {'yes' if verdict['below_both'] else 'NO'}")
            print(f"  {line}")
            md += ["", line, ""]
    print(f"\ndata: {ATTRIBUTION}")
    md.append(f"data: {ATTRIBUTION}")
    if a.out:
        a.out.mkdir(parents=True, exist_ok=True)
        (a.out / "handeye_peers.json").write_text(json.dumps(report, indent=2) + "\n")
        (a.out / "handeye_peers.md").write_text("\n".join(md) + "\n")
        print(f"written: {a.out / 'handeye_peers.json'}, {a.out / 'handeye_peers.md'}")
    return 0 if all(s["must_hold"]["below_both"] for s in report["sets"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
