#!/usr/bin/env python3
"""ferrocal's two-camera rig hand-eye beside OpenCV and vision-calibration on the same corners and split
(issue #32, rigs).

A development baseline, never a dependency of the product (not in CI, not in scripts/setup.sh).
Dependencies as scripts/handeye_peers.py (Python 3.10+):

    pip install opencv-python-headless numpy vision-calibration==0.9.0

The data are SIMULATED by ferrocal's own renderer (`ferrocal handeye simulate --cameras 2`):
rendered images of a flat chessboard, two pinhole cameras with Brown-5 lenses, the ur5 of the
rig study. The robot reports the flange poses of its NOMINAL model while the true robot carries
kinematic errors (truth.json, `robot_errors`); so every method that takes the reported flange
poses as exact (OpenCV, vision-calibration, ferrocal's per-camera hand-eye stage) absorbs the
robot's errors into its transforms and cameras. Only ferrocal's joint adjustment (`--robot ...
--out`) models the robot; it is shown beside, not as a like-for-like peer.

For each mount (eye-to-hand: two fixed cameras, the board on the flange; eye-in-hand: a stereo
head on the flange, the board fixed):

1. `ferrocal handeye simulate --cameras 2` writes the recording (poses.csv with its `split`
   column, cam0/images, cam1/images, truth.json).
2. `ferrocal handeye --images cam0 --images cam1 --robot ur5 --json --corners-out --out
   --rig-out` runs the rig: each camera's own hand-eye fit (JSON `rig.cameras[k].hand_eye_fit`),
   T_cam1_cam0 combined from them (`rig.cameras[1].t_cam_cam0`), and the joint adjustment of
   the robot and both cameras (`rig.joint`). Its `--corners-out` holds camera 0's corners only,
   so camera 1's corners come from ferrocal's single-camera run on cam1/images (same binary,
   same detector, same poses table and split); the script checks that ferrocal's own per-camera
   figures of the rig run are reproduced on those corners, which they can only be if the
   corners are the ones the rig used.
3. On those corners and that split, per camera:
   - OpenCV: calibrateCamera + solvePnP + calibrateHandEye (5 methods) and
     calibrateRobotWorldHandEye (2 methods), per camera, as in handeye_peers.py; T_cam1_cam0
     from the same method's two cameras.
   - vision-calibration 0.9: `run_single_cam_handeye` per camera (robot poses exact / refined),
     T_cam1_cam0 from the two; `run_rig_handeye` on both cameras together (robot poses exact /
     refined; and with its rig extrinsics and intrinsics refined in the hand-eye adjustment,
     k3 free). With the poses exact, the script checks that its own per-camera mean error is
     reproduced (this fixes how its transforms are read).
   - ferrocal: the rig's per-camera hand-eye stage (re-scored here and checked against its own
     figures to 1e-6 px), and the joint adjustment: its own per-camera figures from the JSON and
     re-scored here through the calibrated robot (`ferrocal export --urdf`, then `ferrocal robot
     fk` per pose; checked against its own figures to 1e-4 px, fk prints 6 decimals of mm).
4. Every chain RMS comes from handeye_peers.chain_rms: every corner predicted through the
   flange pose (as reported, except the joint adjustment's calibrated robot), X, W and the
   method's camera; RMS of the 2D error over training and over held-out corners. T_cam1_cam0
   (p_1 = T_cam1_cam0 p_0) is compared with truth.json: translation error in mm, rotation in deg.

Usage:
    python3 scripts/handeye_rig_peers.py [--ferrocal target/debug/ferrocal] [--mounts eye-to-hand eye-in-hand]
                                         [--seed 5] [--out DIR]
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from handeye_peers import (  # noqa: E402
    REPO, T, chain_rms, ferrocal_T, ferrocal_camera, fmt, inv, load_corners, mean_error, opencv_fits,
    quat_wxyz_to_R, run, vc_pose, vc_single_fits, vc_T,
)

DATA_NOTE = ("simulated by ferrocal's renderer (ferrocal handeye simulate --cameras 2): rendered images, "
             "pinhole + Brown-5 lenses, flat chessboard; the robot reports nominal-model flange poses while the "
             "true ur5 has kinematic errors, so methods taking the reported poses as exact absorb them; only "
             "ferrocal's joint adjustment models the robot")


def t_cam1_cam0(mount, X0, W0, X1, W1):
    """p_1 = T_cam1_cam0 p_0 from two cameras' (X, W)."""
    return inv(X1) @ X0 if mount == "eye-in-hand" else inv(W1) @ W0


def pose_error(est, truth):
    if est is None:
        return None
    d = est[:3, :3] @ truth[:3, :3].T
    ang = np.degrees(np.arccos(np.clip((np.trace(d) - 1) / 2, -1, 1)))
    return {"translation_mm": float(np.linalg.norm(est[:3, 3] - truth[:3, 3]) * 1e3), "rotation_deg": float(ang)}


def cam_figures(data, camera, X, W, scale=1.0):
    tr, held, missing = chain_rms(data, camera, X, W, scale)
    return {"heldout_rms_px": held, "train_rms_px": tr, "unprojected": missing}


# --------------------------------------------------------------------------------------------
# ferrocal


def ferrocal_runs(binary, mount, seed, tmp):
    d = tmp / mount
    if (d / "calibrated.urdf").exists():  # --work with the runs already there
        truth = json.loads((d / "truth.json").read_text())
        return d, truth, (d / "command.txt").read_text()
    run([binary, "handeye", "simulate", "--mount", mount, "--robot", "ur5", "--cameras", "2", "--seed", seed,
         "--train", "30", "--test", "10", "--out", d])
    truth = json.loads((d / "truth.json").read_text())
    common = ["--poses", d / "poses.csv", "--robot", "ur5", "--pattern", truth["pattern"], "--mount", mount]
    cmd = [binary, "handeye", "--images", d / "cam0/images", "--images", d / "cam1/images", *common,
           "--json", d / "rig.json", "--corners-out", d / "rig.corners.json", "--out", d / "calibration.json",
           "--rig-out", d / "rig"]
    run(cmd)
    run([binary, "handeye", "--images", d / "cam1/images", *common, "--json", d / "cam1.json",
         "--corners-out", d / "cam1.corners.json"])
    run([binary, "export", "--robot", "ur5", "--calibration", d / "calibration.json", "--urdf", d / "calibrated.urdf"])
    shown = " ".join(str(c) for c in cmd).replace(str(tmp), "$TMP").replace(str(REPO) + "/", "")
    (d / "command.txt").write_text(shown)
    return d, truth, shown


def read_joints(poses_csv):
    rows = [line for line in poses_csv.read_text().splitlines() if not line.startswith("#")]
    return {r["image"]: [float(r[f"q{i}_rad"]) for i in range(1, 7)] for r in csv.DictReader(rows)}


def calibrated_flange(binary, d, joints):
    """T_base_flange of the joint adjustment's calibrated robot, per image name: the exported URDF's
    device->target pose (`ferrocal robot fk`) with the calibration's device frame and tool removed."""
    cal = json.loads((d / "calibration.json").read_text())
    frame = lambda f: T(quat_wxyz_to_R(f["quaternion_wxyz"]), np.asarray(f["translation_mm"]) * 1e-3)  # noqa: E731
    device, tool = frame(cal["device_frame"]), frame(cal["tool"])
    out = {}
    for name, q in joints.items():
        text = run([binary, "robot", "fk", "--robot", d / "calibrated.urdf", "--joints",
                    ",".join(f"{np.degrees(x):.12f}" for x in q)])
        vals = {line.split()[0]: [float(x) for x in line.split()[1:]] for line in text.splitlines()
                if line.split() and line.split()[0] in ("position_mm", "quat_wxyz")}
        fk = T(quat_wxyz_to_R(vals["quat_wxyz"]), np.asarray(vals["position_mm"]) * 1e-3)
        out[name] = inv(device) @ fk @ inv(tool)
    return out


def rescore_ferrocal(label, fit, data, chain_target, tol=1e-6):
    """ferrocal's (X, W, camera, scale) re-scored here; stops unless its own figures are reproduced."""
    scale = fit["target_scale"]["value"] if fit.get("target_scale") else 1.0
    X, W = ferrocal_T(fit["hand_eye"]), ferrocal_T(fit["world"])
    f = cam_figures(dict(data, target=chain_target), ferrocal_camera(fit), X, W, scale)
    for mine, theirs in [(f["train_rms_px"], fit["train_rms_px"]), (f["heldout_rms_px"], fit["heldout_rms_px"])]:
        if abs(mine - theirs) > tol:
            sys.exit(f"{label}: this script's chain RMS {mine} differs from ferrocal's {theirs}")
    return X, W, f


def ferrocal_rows(binary, d, mount, r, datas, chain_target, truth_T):
    rig = r["rig"]
    rows = []
    XW, cams = [], {}
    for k, c in enumerate(rig["cameras"]):
        X, W, f = rescore_ferrocal(f"ferrocal rig cam{k}", c["hand_eye_fit"], datas[k], chain_target)
        XW.append((X, W))
        cams[f"cam{k}"] = f
    t10 = ferrocal_T(rig["cameras"][1]["t_cam_cam0"])
    assert np.allclose(t10, t_cam1_cam0(mount, *XW[0], *XW[1]), atol=1e-9)
    rows.append({"method": "ferrocal handeye (rig): each camera's hand-eye fit, robot poses as reported",
                 **cams, "t_cam1_cam0_error": pose_error(t10, truth_T),
                 "note": "re-scored here = ferrocal's own per-camera figures (1e-6 px)"})

    # The joint adjustment: robot + both cameras; its chain runs through the calibrated robot.
    j = rig["joint"]
    own = {f"cam{k}": {"heldout_rms_px": c["figures"]["heldout_rms_px"], "train_rms_px": c["figures"]["train_rms_px"]}
           for k, c in enumerate(j["cameras"])}
    t10j = ferrocal_T(j["cameras"][1]["t_cam_cam0"])
    note = f"{j['robot_parameters']} robot parameters; figures are ferrocal's own (JSON rig.joint)"
    try:
        flange = calibrated_flange(binary, d, read_joints(d / "poses.csv"))
        X, W0 = ferrocal_T(j["hand_eye"]), ferrocal_T(j["world"])
        for k, c in enumerate(j["cameras"]):
            tk = np.eye(4) if c["t_cam_cam0"] is None else ferrocal_T(c["t_cam_cam0"])
            # eye-to-hand: W_k = T_base_camk = W0 T_cam0_camk; eye-in-hand: X_k = X0 T_cam0_camk.
            Xk, Wk = (X @ inv(tk), W0) if mount == "eye-in-hand" else (X, W0 @ inv(tk))
            data = dict(datas[k], target=chain_target,
                        views=[dict(v, t_base_flange=flange[v["name"]]) for v in datas[k]["views"]])
            fit = {"hand_eye": None, "camera": c["camera"], "train_rms_px": c["figures"]["train_rms_px"],
                   "heldout_rms_px": c["figures"]["heldout_rms_px"]}
            f = cam_figures(data, ferrocal_camera(fit), Xk, Wk)
            for mine, theirs in [(f["train_rms_px"], fit["train_rms_px"]), (f["heldout_rms_px"], fit["heldout_rms_px"])]:
                if abs(mine - theirs) > 1e-4:
                    raise RuntimeError(f"cam{k}: re-scored {mine} px against ferrocal's {theirs} px")
            own[f"cam{k}"]["rescored_heldout_rms_px"] = f["heldout_rms_px"]
            own[f"cam{k}"]["rescored_train_rms_px"] = f["train_rms_px"]
        note += "; re-scored here through the calibrated robot (export --urdf, robot fk) = its own (1e-4 px)"
    except Exception as e:  # noqa: BLE001 - keep the row, say the re-score failed
        note += f"; re-score here FAILED: {e}"
    rows.append({"method": "ferrocal handeye --robot ur5 --out (rig): joint adjustment of robot + both cameras",
                 **own, "t_cam1_cam0_error": pose_error(t10j, truth_T), "note": note, "models_robot": True})
    return rows


# --------------------------------------------------------------------------------------------
# OpenCV and vision-calibration, per camera


def opencv_rig_rows(mount, datas, truth_T):
    fits = [opencv_fits(d) for d in datas]
    rows = []
    for (label, X0, W0, cam0, note0), (_, X1, W1, cam1, note1) in zip(*fits):
        rows.append({"method": f"{label} (per camera)", "cam0": cam_figures(datas[0], cam0, X0, W0),
                     "cam1": cam_figures(datas[1], cam1, X1, W1),
                     "t_cam1_cam0_error": pose_error(t_cam1_cam0(mount, X0, W0, X1, W1), truth_T),
                     "note": f"cam0 {note0}; cam1 {note1}"})
    return rows


def vc_single_rig_rows(mount, datas, truth_T):
    variants = [(False, True), (True, True)]
    fits = [vc_single_fits(d, variants) for d in datas]
    rows = []
    for f0, f1 in zip(*fits):
        label = f"{f0[0]} (per camera)"
        if f0[1] is None or f1[1] is None:
            rows.append({"method": label, "error": f"{f0[4] if f0[1] is None else ''} {f1[4] if f1[1] is None else ''}"})
            continue
        row = {"method": label, "t_cam1_cam0_error": pose_error(t_cam1_cam0(mount, f0[1], f0[2], f1[1], f1[2]), truth_T)}
        notes = []
        for k, (_, X, W, camera, res, refine) in enumerate([f0, f1]):
            row[f"cam{k}"] = cam_figures(datas[k], camera, X, W)
            mean = mean_error(datas[k], camera, X, W)
            if not refine and abs(mean - res.mean_reproj_error) > 1e-3:
                sys.exit(f"{label} cam{k}: mean error {mean} px here against its own {res.mean_reproj_error} px")
            notes.append(f"cam{k} its own mean error {res.mean_reproj_error:.3f} px (here, poses as reported: {mean:.3f})")
        row["note"] = "; ".join(notes)
        rows.append(row)
    return rows


def vc_rig_rows(mount, datas, truth_T):
    import vision_calibration as vc

    eih = mount == "eye-in-hand"
    by_name = {}
    for k, d in enumerate(datas):
        for v in d["views"]:
            if v["split"] == "train":
                by_name.setdefault(v["name"], [None, None])[k] = v
    flange = {n: next(v for v in vs if v is not None)["t_base_flange"] for n, vs in by_name.items()}
    dataset = vc.RigHandeyeDataset(num_cameras=2, views=[
        vc.RigHandeyeView(cameras=[None if v is None else vc.Observation(
            points_3d=[tuple(p) for p in datas[k]["target"][v["ids"]]], points_2d=[tuple(p) for p in v["px"]])
            for k, v in enumerate(vs)], base_se3_gripper=vc_pose(flange[n]))
        for n, vs in sorted(by_name.items())])
    rows = []
    for refine, full in [(False, False), (True, False), (False, True), (True, True)]:
        cfg = vc.RigHandeyeCalibrationConfig()
        cfg.handeye_init.handeye_mode = "EyeInHand" if eih else "EyeToHand"
        cfg.handeye_ba.robot_poses.refine = refine
        if full:
            cfg.handeye_ba.refine_cam_se3_rig = True
            cfg.rig.refine_intrinsics_in_rig_ba = True
            cfg.intrinsics.fix_k3 = False
        label = (f"vision-calibration {vc.__version__} run_rig_handeye (both cameras), robot poses "
                 f"{'refined' if refine else 'exact'}"
                 + (", refine_cam_se3_rig, refine_intrinsics_in_rig_ba, fix_k3=False" if full else ""))
        try:
            res = vc.run_rig_handeye(dataset, cfg)
        except Exception as e:  # noqa: BLE001
            rows.append({"method": label, "error": str(e)})
            continue
        # cam_se3_rig[k] = T_camk_rig; eye-in-hand: gripper_se3_rig = T_flange_rig, base_se3_target;
        # eye-to-hand: rig_se3_base = T_rig_base, gripper_se3_target = T_flange_target.
        cam_rig = [vc_T(p) for p in res.cam_se3_rig]
        row = {"method": label, "t_cam1_cam0_error": pose_error(cam_rig[1] @ inv(cam_rig[0]), truth_T)}
        notes = []
        for k, c in enumerate(res.cameras):
            ki, di = c.intrinsics, c.distortion
            K = np.array([[ki.fx, ki.skew, ki.cx], [0, ki.fy, ki.cy], [0, 0, 1.0]])
            camera = (K, np.array([di.k1, di.k2, di.p1, di.p2, di.k3]))
            if eih:
                X, W = vc_T(res.gripper_se3_rig) @ inv(cam_rig[k]), vc_T(res.base_se3_target)
            else:
                X, W = vc_T(res.gripper_se3_target), inv(vc_T(res.rig_se3_base)) @ inv(cam_rig[k])
            row[f"cam{k}"] = cam_figures(datas[k], camera, X, W)
            mean = mean_error(datas[k], camera, X, W)
            theirs = res.per_cam_reproj_errors[k]
            if not refine and abs(mean - theirs) > 1e-3:
                sys.exit(f"{label} cam{k}: mean error {mean} px here against its own {theirs} px")
            notes.append(f"cam{k} its own mean error {theirs:.3f} px (here, poses as reported: {mean:.3f})")
        row["note"] = "; ".join(notes)
        rows.append(row)
    return rows


# --------------------------------------------------------------------------------------------


def truth_cam1_cam0(truth):
    c = truth["cameras"][1]
    t = ferrocal_T(c["t_cam_cam0"])
    if "t_base_camera" in c:  # check the convention p_1 = T_cam1_cam0 p_0
        w0, w1 = ferrocal_T(truth["cameras"][0]["t_base_camera"]), ferrocal_T(c["t_base_camera"])
        assert np.allclose(inv(w1) @ w0, t, atol=1e-9), "truth.json's t_cam_cam0 is not T_cam1_cam0"
    if "t_flange_camera" in c:
        x0, x1 = ferrocal_T(truth["cameras"][0]["t_flange_camera"]), ferrocal_T(c["t_flange_camera"])
        assert np.allclose(inv(x1) @ x0, t, atol=1e-9), "truth.json's t_cam_cam0 is not T_cam1_cam0"
    return t


def best(rows, prefix, cam):
    cands = [x for x in rows if x["method"].startswith(prefix) and x.get(cam, {}).get("heldout_rms_px") is not None]
    return min(cands, key=lambda x: x[cam]["heldout_rms_px"]) if cands else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    default_bin = next((p for p in [REPO / "target/release/ferrocal", REPO / "target/debug/ferrocal"] if p.exists()),
                       REPO / "target/release/ferrocal")
    ap.add_argument("--ferrocal", type=Path, default=default_bin, help="the ferrocal binary")
    ap.add_argument("--mounts", nargs="+", default=["eye-to-hand", "eye-in-hand"])
    ap.add_argument("--seed", default="5")
    ap.add_argument("--out", type=Path, help="write handeye_rig_peers.json and handeye_rig_peers.md here")
    ap.add_argument("--work", type=Path, help="keep ferrocal's runs here (and reuse them if present) "
                    "instead of a temporary folder")
    a = ap.parse_args()
    import vision_calibration as vc

    report = {"data": DATA_NOTE, "ferrocal": str(a.ferrocal), "opencv": cv2.__version__,
              "vision_calibration": vc.__version__, "seed": a.seed, "mounts": {}}
    md = ["# ferrocal's two-camera rig hand-eye beside OpenCV and vision-calibration\n", f"Data: {DATA_NOTE}.",
          f"OpenCV {cv2.__version__}, vision-calibration {vc.__version__}. Chain RMS in pixels per camera; "
          "held-out images take no part in any fit.\n"]
    ok = True
    with tempfile.TemporaryDirectory() as tmpd:
        tmp = a.work.resolve() if a.work else Path(tmpd)
        for mount in a.mounts:
            d, truth, cmd = ferrocal_runs(a.ferrocal.resolve(), mount, a.seed, tmp)
            r = json.loads((d / "rig.json").read_text())
            c0 = json.loads((d / "rig.corners.json").read_text())
            datas = [load_corners(c0), load_corners(json.loads((d / "cam1.corners.json").read_text()))]
            chain_target = datas[0]["chain_target"]  # the rig's target form (pooled over both cameras)
            truth_T = truth_cam1_cam0(truth)
            rows = ferrocal_rows(a.ferrocal.resolve(), d, mount, r, datas, chain_target, truth_T)
            rows += opencv_rig_rows(mount, datas, truth_T)
            rows += vc_single_rig_rows(mount, datas, truth_T)
            rows += vc_rig_rows(mount, datas, truth_T)
            must = {}
            for who, row in [("rig_stage", rows[0]), ("joint_adjustment", rows[1])]:
                for cam in ("cam0", "cam1"):
                    ours = row[cam]["heldout_rms_px"]
                    b_cv, b_vc = best(rows, "OpenCV", cam), best(rows, "vision-calibration", cam)
                    must[f"{who}_{cam}"] = {
                        "ferrocal_heldout_rms_px": ours,
                        "opencv_best": b_cv["method"], "opencv_best_heldout_rms_px": b_cv[cam]["heldout_rms_px"],
                        "vision_calibration_best": b_vc["method"],
                        "vision_calibration_best_heldout_rms_px": b_vc[cam]["heldout_rms_px"],
                        "below_both": ours < b_cv[cam]["heldout_rms_px"] and ours < b_vc[cam]["heldout_rms_px"]}
            ok &= all(m["below_both"] for k, m in must.items() if k.startswith("joint"))
            n = {k: (sum(v["split"] == "train" for v in dd["views"]), sum(v["split"] == "test" for v in dd["views"]))
                 for k, dd in zip(("cam0", "cam1"), datas)}
            report["mounts"][mount] = {"pattern": truth["pattern"], "ferrocal_command": cmd,
                                       "views_train_test": n, "rows": rows, "comparisons": must}
            head = (f"{mount} (ur5, {truth['pattern']}, seed {a.seed}; cam0 {n['cam0'][0]} training + "
                    f"{n['cam0'][1]} held-out images, cam1 {n['cam1'][0]} + {n['cam1'][1]})")
            print(f"\n{head}\n  ferrocal: {cmd}")
            print(f"  {'method':<118} {'cam0 held':>9} {'cam0 trn':>8} {'cam1 held':>9} {'cam1 trn':>8} "
                  f"{'T10 mm':>8} {'T10 deg':>8}")
            md += [f"## {head}\n", f"`{cmd}`\n",
                   "| method | cam0 held-out | cam0 train | cam1 held-out | cam1 train | T_cam1_cam0 err mm | deg |",
                   "| --- | --- | --- | --- | --- | --- | --- |"]
            for x in rows:
                g = lambda cam, key: x.get(cam, {}).get(key)  # noqa: E731
                e = x.get("t_cam1_cam0_error") or {}
                cells = [fmt(g("cam0", "heldout_rms_px")), fmt(g("cam0", "train_rms_px")),
                         fmt(g("cam1", "heldout_rms_px")), fmt(g("cam1", "train_rms_px")),
                         fmt(e.get("translation_mm")), fmt(e.get("rotation_deg"))]
                print(f"  {x['method']:<118} {cells[0]:>9} {cells[1]:>8} {cells[2]:>9} {cells[3]:>8} "
                      f"{cells[4]:>8} {cells[5]:>8}" + (f"  ERROR {x['error']}" if x.get("error") else ""))
                md.append(f"| {x['method']} | " + " | ".join(cells) + " |")
            for k, m in must.items():
                line = (f"{k}: ferrocal {fmt(m['ferrocal_heldout_rms_px'])} px held out; OpenCV best "
                        f"{fmt(m['opencv_best_heldout_rms_px'])} ({m['opencv_best']}); vision-calibration best "
                        f"{fmt(m['vision_calibration_best_heldout_rms_px'])} ({m['vision_calibration_best']}): "
                        f"below both: {'yes' if m['below_both'] else 'NO'}")
                print(f"  {line}")
                md.append(f"\n{line}")
            md.append("")
    print(f"\ndata: {DATA_NOTE}")
    if a.out:
        a.out.mkdir(parents=True, exist_ok=True)
        (a.out / "handeye_rig_peers.json").write_text(json.dumps(report, indent=2) + "\n")
        (a.out / "handeye_rig_peers.md").write_text("\n".join(md) + "\n")
        print(f"written: {a.out / 'handeye_rig_peers.json'}, {a.out / 'handeye_rig_peers.md'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
