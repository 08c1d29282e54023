"""Robot models (MJCF) and their specs, shipped inside the wheel as ``eaco_jax.robots``.

Each robot is an MJCF file plus a JSON spec beside it (``<name>.json``): actuated joint names in
control order, the standing keyframe, control rate, solver settings for fast and for accurate
simulation, the torso, the feet and the fall thresholds, and (NAO) the motor datasheet with its
sources, from which :func:`motor_constants` derives every actuator constant of the MJCF. Robot
constants live here, never in the algorithms. ``load_robot(name)`` reads the spec;
``load_model(spec, ...)`` builds the ``mujoco.MjModel`` (floor slope, solver accuracy) with the
sensors the rollouts read: ``torso_pos`` (3), ``torso_up`` (3, the torso's z axis in world
coordinates) and ``sole_pos_<geom>`` (3) per foot contact geom.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import math
from pathlib import Path
from typing import Any

ROBOTS_DIR = Path(__file__).resolve().parent


@dataclasses.dataclass(frozen=True)
class RobotSpec:
    """Static description of a robot (hashable, so it can be static config of a jitted problem)."""

    name: str
    xml_path: str
    gait: str  # "biped" (walk engine + leg IK) or "quadruped" (phase oscillator)
    joint_names: tuple[str, ...]
    stand_ctrl: tuple[float, ...]
    stand_root: tuple[float, ...]  # free joint qpos: xyz + quaternion (wxyz)
    joint_lower: tuple[float, ...]
    joint_upper: tuple[float, ...]
    control_dt: float
    solver_fast: tuple[tuple[str, float], ...]
    solver_accurate: tuple[tuple[str, float], ...]
    torso_body: str
    foot_geoms: tuple[str, ...]
    nominal_torso_height: float
    fall_height: float
    fall_tilt_deg: float
    geometry: tuple[tuple[str, float], ...]
    position_servo: tuple[tuple[str, float], ...] = ()
    # per actuator, of the share of a motor it drives (half a motor for a coupled pair):
    stall_torque: tuple[float, ...] = ()  # [N m]
    no_load_speed: tuple[float, ...] = ()  # [rad/s]
    nominal_torque: tuple[float, ...] = ()  # continuous torque [N m]
    coupled_joints: tuple[tuple[str, str], ...] = ()  # (leader, follower): one motor, equal angle
    motor_tolerances: tuple[tuple[str, float], ...] = ()  # datasheet spread (fraction)

    @property
    def nu(self) -> int:
        return len(self.joint_names)

    def geom(self, key: str) -> float:
        """A named geometric constant (e.g. ``"thigh"``) of the robot."""
        return dict(self.geometry)[key]

    @property
    def has_motors(self) -> bool:
        """Whether the spec carries a motor datasheet (torque-speed envelope per actuator)."""
        return bool(self.stall_torque)

    def solver(self, accuracy: str) -> dict[str, float]:
        if accuracy not in ("fast", "accurate"):
            raise ValueError(f"accuracy must be 'fast' or 'accurate', got {accuracy!r}")
        return dict(self.solver_fast if accuracy == "fast" else self.solver_accurate)


def known_robots() -> list[str]:
    """Names of the robots that have a spec in this folder."""
    return sorted(p.stem for p in ROBOTS_DIR.glob("*.json"))


def _resolve_xml(ref: str) -> Path:
    if ref.startswith("brax:"):
        found = importlib.util.find_spec("brax")
        if found is None or not found.submodule_search_locations:
            raise ValueError("this robot uses an asset of the brax package; `pip install brax`")
        return Path(list(found.submodule_search_locations)[0]) / ref.removeprefix("brax:")
    return ROBOTS_DIR / ref


def motor_constants(raw: dict[str, Any], joint_names: list[str]) -> dict[str, list[float]]:
    """Per actuator constants derived from a spec's ``motors`` datasheet block.

    Keys: ``stall``, ``no_load_speed``, ``nominal``, ``back_emf`` (= stall / no-load speed),
    ``damping`` (back-EMF plus the friction loss as viscous drag matched at the no-load speed),
    ``armature`` (rotor inertia x ratio^2) and ``kp`` (stall / the servo's full-voltage error).
    A joint that shares its motor with another (``coupled_joints``) gets half of every
    torque-like constant, so the pair acts as one motor on the shared angle.
    """
    motors = raw["motors"]
    shared = {j for pair in raw.get("coupled_joints", []) for j in pair}
    out: dict[str, list[float]] = {k: [] for k in (
        "stall", "no_load_speed", "nominal", "back_emf", "damping", "armature", "kp")}
    for name in joint_names:
        key = name[1:] if name[:1] in "LR" and name[1:] in motors["joints"] else name
        if key not in motors["joints"]:
            raise ValueError(f"joint {name!r} has no motor in the spec's 'motors.joints'")
        mtype, ratio = motors["joints"][key]
        m = motors["types"][str(mtype)]
        share = 0.5 if name in shared else 1.0
        stall = m["stall_mNm"] * 1e-3 * ratio * share
        speed = m["no_load_rpm"] * 2.0 * math.pi / 60.0 / ratio
        out["stall"].append(stall)
        out["no_load_speed"].append(speed)
        out["nominal"].append(m["nominal_mNm"] * 1e-3 * ratio * share)
        out["back_emf"].append(stall / speed)
        out["damping"].append((1.0 + motors["frictionloss_fraction"]) * stall / speed)
        out["armature"].append(m["rotor_inertia_kgm2"] * ratio**2 * share)
        out["kp"].append(stall / motors["servo_full_voltage_error_rad"])
    return out


def load_robot(name: str) -> RobotSpec:
    """The :class:`RobotSpec` of a known robot (``"nao"``, ``"ant"``); unknown names raise."""
    path = ROBOTS_DIR / f"{name}.json"
    if not isinstance(name, str) or not path.is_file():
        raise ValueError(f"unknown robot {name!r}; known robots: {', '.join(known_robots())}")
    raw: dict[str, Any] = json.loads(path.read_text())
    xml = _resolve_xml(raw["xml"])
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(xml))
    lower, upper = [], []
    for jn in raw["joint_names"]:
        j = model.joint(jn)
        lower.append(float(j.range[0]))
        upper.append(float(j.range[1]))
    return RobotSpec(
        name=raw["name"],
        xml_path=str(xml),
        gait=raw["gait"],
        joint_names=tuple(raw["joint_names"]),
        stand_ctrl=tuple(float(v) for v in raw["stand_ctrl"]),
        stand_root=tuple(float(v) for v in raw["stand_root"]),
        joint_lower=tuple(lower),
        joint_upper=tuple(upper),
        control_dt=float(raw["control_dt"]),
        solver_fast=tuple(sorted(raw["solver"]["fast"].items())),
        solver_accurate=tuple(sorted(raw["solver"]["accurate"].items())),
        torso_body=raw["torso_body"],
        foot_geoms=tuple(raw["foot_geoms"]),
        nominal_torso_height=float(raw["nominal_torso_height"]),
        fall_height=float(raw["fall_height"]),
        fall_tilt_deg=float(raw["fall_tilt_deg"]),
        geometry=tuple(sorted(raw.get("geometry", {}).items())),
        position_servo=tuple(sorted(raw.get("position_servo", {}).items())),
        **_motor_fields(raw),
    )


def _motor_fields(raw: dict[str, Any]) -> dict[str, Any]:
    if "motors" not in raw:
        return {}
    mc = motor_constants(raw, raw["joint_names"])
    return dict(
        stall_torque=tuple(mc["stall"]),
        no_load_speed=tuple(mc["no_load_speed"]),
        nominal_torque=tuple(mc["nominal"]),
        coupled_joints=tuple(tuple(p) for p in raw.get("coupled_joints", [])),
        motor_tolerances=tuple(sorted(raw["motors"].get("tolerances", {}).items())),
    )


def load_model(spec: RobotSpec, slope_deg: float = 0.0, accuracy: str = "fast"):
    """Compile the robot's ``mujoco.MjModel``: floor tilted by ``slope_deg`` (uphill along +x),
    solver settings ``accuracy`` ("fast" | "accurate"), torso and sole sensors, position servos."""
    return _model_spec(spec, slope_deg, accuracy)[1]


def model_xml(spec: RobotSpec, slope_deg: float = 0.0, accuracy: str = "fast") -> str:
    """The MJCF text of :func:`load_model`'s model (slope, solver and sensors included), for
    exporting a run that replays on plain MuJoCo."""
    return _model_spec(spec, slope_deg, accuracy)[0].to_xml()


def _model_spec(spec: RobotSpec, slope_deg: float, accuracy: str):
    import mujoco

    if not math.isfinite(slope_deg) or abs(slope_deg) >= 45.0:
        raise ValueError(f"slope_deg must be finite and within (-45, 45), got {slope_deg}")
    ms = mujoco.MjSpec.from_file(spec.xml_path)
    opts = spec.solver(accuracy)
    ms.option.timestep = opts["timestep"]
    ms.option.iterations = int(opts["iterations"])
    ms.option.ls_iterations = int(opts["ls_iterations"])
    if "tolerance" in opts:
        ms.option.tolerance = float(opts["tolerance"])
    ms.option.solver = mujoco.mjtSolver.mjSOL_NEWTON
    ms.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    ms.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_EULERDAMP
    floor = ms.geom("floor")
    half = math.radians(-slope_deg) / 2.0  # rotation about +y by -slope raises the +x side
    floor.quat = [math.cos(half), 0.0, math.sin(half), 0.0]
    if spec.position_servo:
        servo = dict(spec.position_servo)
        for act in ms.actuators:
            j = ms.joint(act.target)
            act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
            act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            act.gainprm[0] = servo["kp"]
            act.biasprm[:3] = [0.0, -servo["kp"], 0.0]
            act.gear[0] = 1.0
            act.ctrlrange = list(j.range)
            act.forcelimited = 1
            act.forcerange = [-servo["forcerange"], servo["forcerange"]]
    names = {s.name for s in ms.sensors}
    if "torso_pos" not in names:
        body = ms.body(spec.torso_body)
        body.add_site(name="torso_site", pos=[0, 0, 0], size=[0.01, 0, 0])
        ms.add_sensor(name="torso_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                      objtype=mujoco.mjtObj.mjOBJ_SITE, objname="torso_site")
        ms.add_sensor(name="torso_up", type=mujoco.mjtSensor.mjSENS_FRAMEZAXIS,
                      objtype=mujoco.mjtObj.mjOBJ_SITE, objname="torso_site")
    for geom in spec.foot_geoms:  # sole positions for the gait-quality metrics
        if f"sole_pos_{geom}" not in names:
            ms.add_sensor(name=f"sole_pos_{geom}", type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                          objtype=mujoco.mjtObj.mjOBJ_GEOM, objname=geom)
    model = ms.compile()
    order = [model.actuator(i).name or model.joint(model.actuator_trnid[i, 0]).name
             for i in range(model.nu)]
    joints = [model.joint(model.actuator_trnid[i, 0]).name for i in range(model.nu)]
    if joints != list(spec.joint_names):
        raise ValueError(f"robot {spec.name}: actuator order {order} != spec joint_names")
    return ms, model


def stand_qpos(spec: RobotSpec, model) -> list[float]:
    """Full ``qpos`` of the standing keyframe (root pose + joint angles = stand_ctrl)."""
    qpos = [0.0] * model.nq
    qpos[:7] = list(spec.stand_root)
    for name, value in zip(spec.joint_names, spec.stand_ctrl, strict=True):
        qpos[model.joint(name).qposadr[0]] = value
    return qpos
