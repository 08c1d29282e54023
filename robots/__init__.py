"""Robot models (MJCF) and their specs, shipped inside the wheel as ``eaco_jax.robots``.

Each robot is an MJCF file plus a JSON spec beside it (``<name>.json``): actuated joint names in
control order, the standing keyframe, control rate, solver settings for fast and for accurate
simulation, the torso, the feet and the fall thresholds. Robot constants live here, never in the
algorithms. ``load_robot(name)`` reads the spec; ``load_model(spec, ...)`` builds the
``mujoco.MjModel`` (floor slope, solver accuracy) with two sensors every rollout reads:
``torso_pos`` (3) and ``torso_up`` (3, the torso's z axis in world coordinates).
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

    @property
    def nu(self) -> int:
        return len(self.joint_names)

    def geom(self, key: str) -> float:
        """A named geometric constant (e.g. ``"thigh"``) of the robot."""
        return dict(self.geometry)[key]

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
    )


def load_model(spec: RobotSpec, slope_deg: float = 0.0, accuracy: str = "fast"):
    """Compile the robot's ``mujoco.MjModel``: floor tilted by ``slope_deg`` (uphill along +x),
    solver settings ``accuracy`` ("fast" | "accurate"), torso sensors, position servos."""
    import mujoco

    if not math.isfinite(slope_deg) or abs(slope_deg) >= 45.0:
        raise ValueError(f"slope_deg must be finite and within (-45, 45), got {slope_deg}")
    ms = mujoco.MjSpec.from_file(spec.xml_path)
    opts = spec.solver(accuracy)
    ms.option.timestep = opts["timestep"]
    ms.option.iterations = int(opts["iterations"])
    ms.option.ls_iterations = int(opts["ls_iterations"])
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
    model = ms.compile()
    order = [model.actuator(i).name or model.joint(model.actuator_trnid[i, 0]).name
             for i in range(model.nu)]
    joints = [model.joint(model.actuator_trnid[i, 0]).name for i in range(model.nu)]
    if joints != list(spec.joint_names):
        raise ValueError(f"robot {spec.name}: actuator order {order} != spec joint_names")
    return model


def stand_qpos(spec: RobotSpec, model) -> list[float]:
    """Full ``qpos`` of the standing keyframe (root pose + joint angles = stand_ctrl)."""
    qpos = [0.0] * model.nq
    qpos[:7] = list(spec.stand_root)
    for name, value in zip(spec.joint_names, spec.stand_ctrl, strict=True):
        qpos[model.joint(name).qposadr[0]] = value
    return qpos
