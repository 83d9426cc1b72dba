#!/usr/bin/env python3
"""Renders ferrocal's HTML reports in a real headless browser and checks their layout.

For each report: a screenshot at 1400 px width (PNG, the whole page with its details folded),
the page's height in screens of 1400 x 900 px, every element that sticks out to the right of
the page (a layout bug: a table or figure wider than the window), and every 3-D scene turned by
its script (at the default angle it must draw what the Rust side drew; at other angles it must
stay inside its figure). Fails (exit 1) when an element overflows, a scene is drawn wrong, or a
report is longer than --max-screens before its folded details.

    scripts/report_check.py --out out/screens                 # makes the reports, then checks them
    scripts/report_check.py --out out/screens a.html b.html   # checks the given reports only

Needs Chromium (Debian: `apt-get install chromium`) and, to make the reports, the built binary
(`cargo build --release -p ferrocal`, or --ferrocal PATH) and ../shared/data beside the checkout.
The reports are made from the shared recordings (their attributions are in each report).
"""

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

WIDTH_PX = 1400
SCREEN_PX = 900

MEASURE = """
<script>
window.addEventListener('load', () => {
  const w = document.documentElement.clientWidth;
  const over = [];
  for (const e of document.body.querySelectorAll('*')) {
    if (e.closest('details:not([open])') && e.tagName !== 'SUMMARY') continue;
    const r = e.getBoundingClientRect();
    if (r.width > 0 && r.right > w + 1) {
      const inScroller = e.parentElement && e.parentElement.closest('table, pre');
      if (!inScroller) over.push(e.tagName.toLowerCase() + (e.id ? '#' + e.id : '') + ' ' + Math.round(r.right) + 'px');
    }
  }
  // Every 3-D scene: the script, turned to the default angle, draws what Rust drew (within the
  // 0.1 px rounding); turned to other angles, everything stays inside the figure.
  const scenes = [];
  const coords = (svg) => [...svg.querySelectorAll('[data-p]')].flatMap((e) => {
    const t = e.tagName.toLowerCase();
    if (t === 'circle') return [+e.getAttribute('cx'), +e.getAttribute('cy')];
    if (t === 'text') return [+e.getAttribute('x'), +e.getAttribute('y')];
    return e.getAttribute('points').split(/[ ,]/).map(Number);
  });
  document.querySelectorAll('svg.scene3d').forEach((svg, i) => {
    const drawn = coords(svg);
    let worst = 0, outside = 0;
    if (typeof svg.turn !== 'function') { scenes.push({scene: i, error: 'no script'}); return; }
    svg.turn(...svg.home);
    coords(svg).forEach((v, j) => { worst = Math.max(worst, Math.abs(v - drawn[j])); });
    const [w, h] = svg.getAttribute('viewBox').split(' ').slice(2).map(Number);
    for (const [a, b] of [[0, 0], [1.2, 0.9], [-2.5, -0.6], [3.0, 1.5]]) {
      svg.turn(a, b);
      const c = coords(svg);
      for (let j = 0; j + 1 < c.length; j += 2) {
        if (!(c[j] >= 0 && c[j] <= w && c[j + 1] >= 0 && c[j + 1] <= h)) outside += 1;
      }
    }
    svg.turn(...svg.home);
    scenes.push({scene: i, values: drawn.length, worst_px: worst, outside: outside});
  });
  const out = document.createElement('pre');
  out.id = 'ferrocal-layout';
  out.textContent = JSON.stringify({height: document.documentElement.scrollHeight,
                                    width: document.documentElement.scrollWidth, viewport: w, overflow: over,
                                    scenes: scenes});
  document.body.appendChild(out);
});
</script>
"""


def chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    sys.exit("report_check: Chromium not found; install it (Debian: apt-get install chromium)")


def browser(args, html, height=SCREEN_PX, extra=()):
    cmd = [chromium(), "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
           f"--window-size={WIDTH_PX},{height}", *extra, html.resolve().as_uri()]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def check(html, out_dir):
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / html.name
        text = html.read_text(encoding="utf-8")
        probe.write_text(text.replace("</body>", MEASURE + "</body>"), encoding="utf-8")
        dom = browser(None, probe, extra=("--dump-dom", "--virtual-time-budget=5000")).stdout
    m = re.search(r'<pre id="ferrocal-layout">(.*?)</pre>', dom, re.S)
    if not m:
        return {"report": str(html), "error": "the page did not finish loading"}
    layout = json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    shot = out_dir / (html.parent.name + "-" + html.stem + ".png")
    browser(None, html, height=min(layout["height"], 16000), extra=(f"--screenshot={shot}",))
    layout.update(report=str(html), screens=layout["height"] / SCREEN_PX, screenshot=str(shot))
    return layout


def make_reports(ferrocal, data, work):
    """Runs the commands whose reports are checked; returns the HTML files."""
    work.mkdir(parents=True, exist_ok=True)
    run = lambda *a: subprocess.run([ferrocal, *map(str, a)], capture_output=True, text=True)
    out = []
    left = data / "opencv_stereo" / "left*.jpg"
    right = data / "opencv_stereo" / "right*.jpg"
    run("camera", "calibrate", "--images", left, "--pattern", "chessboard:9x6:25mm", "--fix-aspect",
        "--test-every", "3", "--json", work / "camera.json", "--report", work / "camera.html")
    out.append(work / "camera.html")
    run("camera", "stereo", "--left", left, "--right", right, "--pattern", "chessboard:9x6:25mm",
        "--fix-aspect", "--json", work / "stereo.json", "--report", work / "stereo.html")
    out.append(work / "stereo.html")
    table = work / "ur5.csv"
    run("import", "ur5", "--input", data / "ur5_tracker" / "ur5_grid_train.csv", "--out", table)
    run("calibrate", "--robot", "ur5", "--measurements", table, "--out", work / "cal.json",
        "--json", work / "calibrate.json", "--report", work / "calibrate.html")
    out.append(work / "calibrate.html")
    run("diagnose", "--robot", "ur5", "--measurements", table, "--json", work / "diagnose.json",
        "--report", work / "diagnose.html")
    out.append(work / "diagnose.html")
    sim = work / "handeye-sim"
    if not sim.exists():
        run("handeye", "simulate", "--mount", "eye-to-hand", "--seed", "4", "--out", sim)
    truth = json.loads((sim / "truth.json").read_text())
    run("handeye", "--images", sim / "images", "--poses", sim / "poses.csv", "--pattern", truth["pattern"],
        "--mount", "eye-to-hand", "--intrinsics", sim / "camera.yaml", "--json", work / "handeye.json",
        "--report", work / "handeye.html")
    out.append(work / "handeye.html")
    demo = work / "demo"
    shutil.rmtree(demo, ignore_errors=True)
    run("--keep", "demo", "--quick", "--data", data, "--out", demo)
    out.append(demo / "index.html")
    return [p for p in out if p.exists()] + [Path(f"missing: {p}") for p in out if not p.exists()]


def main():
    here = Path(__file__).resolve().parent.parent
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("reports", nargs="*", type=Path, help="HTML reports to check (default: make them)")
    ap.add_argument("--out", type=Path, default=here / "out" / "screens", help="folder for screenshots")
    ap.add_argument("--ferrocal", default=str(here / "target" / "release" / "ferrocal"))
    ap.add_argument("--data", type=Path, default=here.parent / "shared" / "data")
    ap.add_argument("--max-screens", type=float, default=8.0)
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    reports = a.reports or make_reports(a.ferrocal, a.data, a.out / "reports")
    failed = False
    rows = []
    for html in reports:
        if not html.exists():
            print(f"{html}: not written", file=sys.stderr)
            failed = True
            continue
        r = check(html, a.out)
        rows.append(r)
        bad_scenes = [s for s in r.get("scenes", []) if "error" in s or s["worst_px"] > 0.11 or s["outside"]]
        bad = "error" in r or r["overflow"] or r["screens"] > a.max_screens or bad_scenes
        failed |= bool(bad)
        if "error" in r:
            print(f"FAIL {html}: {r['error']}")
            continue
        print(f"{'FAIL' if bad else 'ok  '} {html}: {r['height']} px = {r['screens']:.1f} screens of "
              f"{WIDTH_PX} x {SCREEN_PX}, {len(r['overflow'])} overflowing element(s) {r['overflow'][:5]}; "
              f"{len(r.get('scenes', []))} 3-D scene(s), {len(bad_scenes)} drawn wrong {bad_scenes[:3]}; "
              f"screenshot {r['screenshot']}")
    (a.out / "layout.json").write_text(json.dumps(rows, indent=1))
    print(f"{sum(1 for r in rows if 'error' not in r)} report(s) checked; "
          f"{'a check failed' if failed else 'all within ' + str(a.max_screens) + ' screens, none overflows'}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
