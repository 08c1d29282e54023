"""Why does a standing NAO heat its hip roll? Per-joint breakdown of standing still.

Each posture is held for ``--seconds`` on native MuJoCo (CPU, nominal world, the motor limits in
the physics: the same direct-torque step as :mod:`eaco_jax.gait.rollout_native`, one ``MjData``
stepped by ``mj_step``) and the last half of the hold is averaged per leg joint: mean
``|drive torque|`` (as a fraction of the motor's nominal torque), mean position error
``target - q`` (deg), the copper loss and its share of the robot's total, and the winding
temperature after ten minutes at that mean loss (the closed-form step response of
:mod:`eaco_jax.gait.motors`, from 25 C). Per foot: the mean contact force in world axes
(``fy`` > 0 pushes the foot to the robot's left; the left foot's ``fy`` < 0 and the right
foot's ``fy`` > 0 mean the floor pushes the feet inward, i.e. the legs spread against the
floor), the sole's mean roll (deg, how flat it rests) and its lateral position.

Postures (no stepping: step length, foot lift, sway and arm swing 0):

* ``feasibility-stand``: what ``experiments/nao_feasibility.py`` calls standing (the stored gait
  otherwise, its hip-roll compensation and ankle-roll offset included) at each stance height;
* ``flat``: the same with the roll compensations 0 (the IK's own flat-foot roll angles);
* ``keyframe``: the robot's standing keyframe held constant;
* ``width``: ``flat`` at hip height 0.21 m with the feet closer / wider (``step_width``);
* ``hip-roll-comp-only`` / ``ankle-roll-comp-only``: one compensation at a time;
* ``feasibility-stand-kp/2``: a position loop of half the gain.

And the stored walking gait, to see where its heat comes from: per joint, the share of the
copper loss in torque variation faster than one control step (``fast_loss_share``: the loss
less the loss of the torque averaged over each 20 ms control step) and the torque's sign
changes per second, at physics steps of 4, 2 and 1 ms, with the targets held for a control
step (``walk-stored-gait``) or interpolated linearly to the next one
(``walk-stored-gait-interpolated``, what NAO's DCM does: nao.json ``sources.targets``). All
runs here set the targets per physics step themselves (held unless a row says
``interpolate``), whatever the spec's ``motors.interpolate_targets``.

    python experiments/nao_standing_heat.py --out experiments/results/nao_standing_heat.json
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from pathlib import Path

import mujoco
import numpy as np
from common import write_results

from eaco_jax.gait import motors as mo
from eaco_jax.gait import quality as ql
from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.robot import load_robot
from eaco_jax.gait.rollout_native import initial_state, native_model, nominal_motor, torque_model
from eaco_jax.gait.worlds import actuated_dofs, couple_controls

LEGS = ("HipYawPitch", "HipRoll", "HipPitch", "KneePitch", "AnklePitch", "AnkleRoll")
STILL = {"step_length": 0.0, "foot_lift": 0.0, "lateral_sway": 0.0, "arm_swing": 0.0}
STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS
STORED = "experiments/results/nao_best_gait.json"
HEIGHTS = (0.19, 0.21, 0.24)
WIDTHS = (-0.01, 0.0, 0.02, 0.04)


def stand_params(stored: np.ndarray, **changes: float) -> np.ndarray:
    """The stored gait with no stepping and ``changes`` applied."""
    x = stored.copy()
    for n, v in {**STILL, **changes}.items():
        x[we.PARAM_NAMES.index(n)] = v
    return x


def hold(spec, controls: np.ndarray, mm: mo.MotorModel, *, kp_scale: float = 1.0,
         timestep: float | None = None, interpolate: bool = False) -> dict:
    """Step ``controls`` ``(T, nu)`` (one per control step) with the limits in the physics and
    average the second half. ``kp_scale`` scales the servo gain (a softer position loop),
    ``timestep`` replaces the model's physics step (the control step stays
    ``spec.control_dt``), ``interpolate``: the targets move linearly to the next control
    step's over its physics steps (:func:`eaco_jax.gait.motors.physics_targets`) instead of
    being held."""
    base = native_model(spec, 0.0, "fast")
    model = copy.copy(torque_model(spec, 0.0, "fast"))
    if timestep is not None:
        model.opt.timestep = timestep
    dt = float(model.opt.timestep)
    k = round(spec.control_dt / dt)
    mp0 = nominal_motor(spec, base)
    mp = ql.MotorParams(*(np.asarray(a, np.float64) for a in mp0))
    mp = mp._replace(kp=mp.kp * kp_scale)
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, initial_state(spec, base, 0.0), STATE)
    qadr = np.array([base.joint(n).qposadr[0] for n in spec.joint_names])
    dofs = np.asarray(actuated_dofs(base, spec))
    feet = {side: [model.geom(g).id for g in spec.foot_geoms if g.startswith(side[0].lower())]
            for side in ("left", "right")}
    foot_body = {s: model.geom_bodyid[ids[0]] for s, ids in feet.items()}
    steps = controls.shape[0] * k
    keep = steps // 2
    taus, speeds, errs = [], [], []
    force = {s: np.zeros(3) for s in feet}
    roll = {s: 0.0 for s in feet}
    y = {s: 0.0 for s in feet}
    f6 = np.zeros(6)
    for s in range(steps):
        i, j = divmod(s, k)
        u = controls[i]
        if interpolate:
            u = u + (j / k) * (controls[min(i + 1, len(controls) - 1)] - u)
        q, qd = data.qpos[qadr].copy(), data.qvel[dofs].copy()
        tau = ql.motor_torque(q, qd, u, mp, mm, np)
        data.ctrl[:] = tau
        mujoco.mj_step(model, data)
        if data.qpos[2] < spec.fall_height:
            return {"fell": True}
        if s < steps - keep:
            continue
        taus.append(tau)
        speeds.append(qd)
        errs.append(np.clip(u, mp.ctrl_lo, mp.ctrl_hi) - q)
        for side, ids in feet.items():
            for c in range(data.ncon):
                con = data.contact[c]
                if con.geom1 in ids or con.geom2 in ids:
                    mujoco.mj_contactForce(model, data, c, f6)
                    fw = con.frame.reshape(3, 3).T @ f6[:3]
                    force[side] += fw if fw[2] > 0 else -fw  # on the foot: supports it
            rot = data.xmat[foot_body[side]].reshape(3, 3)
            roll[side] += np.degrees(np.arctan2(rot[2, 1], rot[2, 2]))
            y[side] += data.xpos[foot_body[side]][1]
    tau, qd, err = np.asarray(taus), np.asarray(speeds), np.asarray(errs)
    loss = mo.copper_loss(mo.current(tau, qd, mm, np), mm, np).mean(0)
    # the loss if the torque were its mean over each control step: what is left is the share
    # of the copper loss in torque variation faster than one control step (20 ms)
    m = tau.shape[0] // k * k
    tau_c = tau[:m].reshape(-1, k, spec.nu).mean(1)
    qd_c = qd[:m].reshape(-1, k, spec.nu).mean(1)
    loss_c = mo.copper_loss(mo.current(tau_c, qd_c, mm, np), mm, np).mean(0)
    flips = (np.diff(np.sign(tau), axis=0) != 0).sum(0) / (tau.shape[0] * dt)
    nominal = np.asarray(spec.nominal_torque)
    t10 = mo.step_response(600.0, loss, mm, np)[..., 0] + mm.t_ambient
    joints = {}
    for j, n in enumerate(spec.joint_names):
        if n[1:] in LEGS:
            joints[n] = {"tau_over_nominal": float(np.abs(tau[:, j]).mean() / nominal[j]),
                         "error_deg": float(np.degrees(err[:, j].mean())),
                         "loss_w": float(loss[j]), "loss_share": float(loss[j] / loss.sum()),
                         "fast_loss_share": float(1.0 - loss_c[j] / max(loss[j], 1e-12)),
                         "torque_sign_flips_per_s": float(flips[j]),
                         "winding_10min_c": float(t10[j])}
    hot = max(joints, key=lambda n: joints[n]["winding_10min_c"])
    return {"fell": False, "timestep": dt, "kp_scale": kp_scale, "interpolate": interpolate,
            "joints": joints,
            "hottest": hot, "hottest_10min_c": joints[hot]["winding_10min_c"],
            "loss_total_w": float(loss.sum()), "torso_x_m": float(data.qpos[0]),
            "feet": {s: {"force_n": (force[s] / keep).tolist(), "roll_deg": roll[s] / keep,
                         "y_m": y[s] / keep} for s in feet}}


def case_row(kind: str, changes: dict, r: dict) -> dict:
    """One output row, printed as it is made."""
    row = {"kind": kind, "set": changes, **r}
    if r["fell"]:
        print(f"{kind:22s} {json.dumps(changes):52s} fell")
        return row
    j = r["joints"]
    print(f"{kind:22s} {json.dumps(changes):52s} hottest {r['hottest']:12s} "
          f"{r['hottest_10min_c']:6.1f} C  loss {r['loss_total_w']:5.2f} W  hip roll "
          f"{j['LHipRoll']['loss_w']:.2f}/{j['RHipRoll']['loss_w']:.2f} W  fy "
          f"{r['feet']['left']['force_n'][1]:+.2f}/{r['feet']['right']['force_n'][1]:+.2f} N")
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--out", type=Path,
                    default=Path("experiments/results/nao_standing_heat.json"))
    a = ap.parse_args()
    t0 = time.perf_counter()
    import jax.numpy as jnp

    spec = load_robot("nao")
    mm = mo.motor_model(spec)
    stored = np.asarray(json.loads(Path(STORED).read_text())["vector"], np.float32)
    n = int(round(a.seconds / spec.control_dt))

    def gait(x: np.ndarray) -> np.ndarray:
        c = we.control_sequence(jnp.asarray(x), n, spec)
        return np.asarray(couple_controls(c, spec, xp=jnp), np.float64)

    flat = {"hip_roll_comp": 0.0, "ankle_roll_comp": 0.0}
    rows = []
    for h in HEIGHTS:
        rows.append(case_row("feasibility-stand", {"hip_height": h},
                             hold(spec, gait(stand_params(stored, hip_height=h)), mm)))
        rows.append(case_row("flat", {"hip_height": h, **flat},
                             hold(spec, gait(stand_params(stored, hip_height=h, **flat)), mm)))
    for name, ch in (("hip-roll-comp-only", {"ankle_roll_comp": 0.0}),
                     ("ankle-roll-comp-only", {"hip_roll_comp": 0.0})):
        rows.append(case_row(name, {"hip_height": 0.21, **ch}, hold(
            spec, gait(stand_params(stored, hip_height=0.21, **ch)), mm)))
    rows.append(case_row("feasibility-stand-kp/2", {"hip_height": 0.21}, hold(
        spec, gait(stand_params(stored, hip_height=0.21)), mm, kp_scale=0.5)))
    for w in WIDTHS:
        ch = {"hip_height": 0.21, "step_width": w, **flat}
        rows.append(case_row("width", ch, hold(spec, gait(stand_params(stored, **ch)), mm)))
    rows.append(case_row("keyframe", {}, hold(
        spec, np.tile(np.asarray(spec.stand_ctrl, np.float64), (n, 1)), mm)))
    for dt in (0.004, 0.002, 0.001):
        rows.append(case_row("walk-stored-gait", {"timestep": dt},
                             hold(spec, gait(stored), mm, timestep=dt)))
    rows.append(case_row("walk-stored-gait-kp/2", {}, hold(spec, gait(stored), mm,
                                                         kp_scale=0.5)))
    for dt in (0.004, 0.001):
        rows.append(case_row("walk-stored-gait-interpolated", {"timestep": dt},
                             hold(spec, gait(stored), mm, timestep=dt, interpolate=True)))
    for h in HEIGHTS:
        rows.append(case_row("flat-interpolated", {"hip_height": h, **flat}, hold(
            spec, gait(stand_params(stored, hip_height=h, **flat)), mm, interpolate=True)))
    get = lambda kind, **ch: next(r for r in rows if r["kind"] == kind and all(  # noqa: E731
        r["set"].get(k) == v for k, v in ch.items()))
    walk = get("walk-stored-gait", timestep=0.004)
    walk_i = get("walk-stored-gait-interpolated", timestep=0.004)
    summary = {
        "feasibility_stand_hottest_10min_c": {
            f"{h:.2f}": get("feasibility-stand", hip_height=h)["hottest_10min_c"]
            for h in HEIGHTS},
        "flat_stand_hottest_10min_c": {
            f"{h:.2f}": get("flat", hip_height=h)["hottest_10min_c"] for h in HEIGHTS},
        "flat_stand_hip_roll_10min_max_c": max(
            max(get("flat", hip_height=h)["joints"][j]["winding_10min_c"]
                for j in ("LHipRoll", "RHipRoll")) for h in HEIGHTS),
        "hip_roll_loss_w_021": {
            k: get(k, hip_height=0.21)["joints"]["RHipRoll"]["loss_w"]
            for k in ("feasibility-stand", "flat", "hip-roll-comp-only",
                      "ankle-roll-comp-only", "feasibility-stand-kp/2")},
        "feet_fy_n_021": {k: [get(k, hip_height=0.21)["feet"][s]["force_n"][1]
                              for s in ("left", "right")]
                          for k in ("feasibility-stand", "flat")},
        "walk_fast_loss_share": {j: walk["joints"][f"L{j}"]["fast_loss_share"]
                                 for j in LEGS[1:]},
        "walk_loss_total_w": {"held": walk["loss_total_w"],
                              "interpolated": walk_i["loss_total_w"]},
        "walk_hottest_10min_c": {"held": walk["hottest_10min_c"],
                                 "interpolated": walk_i["hottest_10min_c"]},
        "walk_interpolated_fast_loss_share": {
            j: walk_i["joints"][f"L{j}"]["fast_loss_share"] for j in LEGS[1:]},
        "walk_interpolated_loss_w": {j: walk_i["joints"][f"L{j}"]["loss_w"] for j in LEGS},
        "walk_held_loss_w": {j: walk["joints"][f"L{j}"]["loss_w"] for j in LEGS},
        "walk_distance_m": {"held": walk["torso_x_m"], "interpolated": walk_i["torso_x_m"]},
        "flat_interpolated_hottest_10min_c": {
            f"{h:.2f}": get("flat-interpolated", hip_height=h)["hottest_10min_c"]
            for h in HEIGHTS},
        "walk_knee_loss_w_by_timestep": {
            str(dt): get("walk-stored-gait", timestep=dt)["joints"]["LKneePitch"]["loss_w"]
            for dt in (0.004, 0.002, 0.001)},
        "walk_fast_loss_share_by_timestep": {
            str(dt): {j: get("walk-stored-gait", timestep=dt)["joints"][f"L{j}"][
                "fast_loss_share"] for j in LEGS[1:]} for dt in (0.004, 0.002, 0.001)},
    }
    write_results(a.out, rows, seconds_held=a.seconds, stored_gait=STORED, summary=summary,
                  seconds=time.perf_counter() - t0)
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
