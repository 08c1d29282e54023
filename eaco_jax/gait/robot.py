"""Robot specs: load a robot (an MJCF model plus a JSON spec) by name or from any path.

A spec names the MJCF file (relative to the spec's folder), the actuated joints in control
order, the standing pose, control rate, solver settings for fast and for accurate simulation,
the torso, the feet and the fall rule, and optionally a motor datasheet with its sources, from
which :func:`motor_constants` derives every actuator constant. Every field is documented in
``docs/robots.md``. The specs shipped with the package live in the data folder ``robots/``
(:data:`ROBOTS_DIR`); robot constants live there or in a user's own spec, never in the
algorithms.

``load_robot(name_or_path)`` reads and checks a spec against its MJCF: a bad spec is one
:class:`~eaco_jax.errors.ProblemError` line naming the field. ``load_model(spec, ...)`` builds
the ``mujoco.MjModel`` (floor slope, solver accuracy) with the sensors the rollouts read:
``torso_pos`` (3), ``torso_up`` (3, the torso's z axis in world coordinates) and
``sole_pos_<geom>`` (3) per foot contact geom.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import json
import math
import re
from pathlib import Path
from typing import Any

from eaco_jax.errors import ProblemError


def _robots_dir() -> Path:
    """The data folder of the shipped specs: ``eaco_jax/robots`` in an installed wheel, the
    repository's top-level ``robots/`` in a source checkout (also an editable install)."""
    package = Path(__file__).resolve().parents[1]
    for folder in (package / "robots", package.parent / "robots"):
        if (folder / "nao.json").is_file():
            return folder
    return package / "robots"


ROBOTS_DIR = _robots_dir()
GAIT_KINDS = ("biped", "quadruped")


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
    force_limit: tuple[float, ...] = ()  # per actuator: the MJCF's |forcerange| (inf: unlimited)
    feet: tuple[str, ...] = ()  # bodies or sites ending the leg chains (default: foot_geoms')
    arm_swing_joints: tuple[str, ...] = ()  # (left, right) joints the biped's arm swing moves
    source: str = ""  # absolute path of the spec file
    digest: str = ""  # sha256 of the spec file and its MJCF (with included files)

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

    @property
    def builtin(self) -> bool:
        """Whether the spec is one shipped in :data:`ROBOTS_DIR` (then its name finds it)."""
        return bool(self.source) and Path(self.source).parent == ROBOTS_DIR

    @property
    def ref(self) -> str:
        """What finds this spec again: the name of a shipped robot, else the spec's path."""
        return self.name if self.builtin or not self.source else self.source

    def solver(self, accuracy: str) -> dict[str, float]:
        if accuracy not in ("fast", "accurate"):
            raise ValueError(f"accuracy must be 'fast' or 'accurate', got {accuracy!r}")
        return dict(self.solver_fast if accuracy == "fast" else self.solver_accurate)


def known_robots() -> list[str]:
    """Names of the robots that have a spec in :data:`ROBOTS_DIR`."""
    return sorted(p.stem for p in ROBOTS_DIR.glob("*.json"))


def spec_path(robot: str | Path) -> Path:
    """The spec file of ``robot``: a shipped robot's name, or a path to a spec ``.json``."""
    text = str(robot)
    known = ", ".join(known_robots())
    if text.lower().endswith((".xml", ".mjcf")):
        raise ProblemError(f"{text} is an MJCF model, not a robot spec: write a spec .json that "
                           "names it in 'xml' (see docs/robots.md) and pass that")
    if isinstance(robot, Path) or text.endswith(".json") or "/" in text or "\\" in text:
        path = Path(text).expanduser()
        if not path.is_file():
            raise ProblemError(f"robot spec {text} does not exist; give a spec .json file or "
                               f"a known robot: {known}")
        return path.resolve()
    path = ROBOTS_DIR / f"{text}.json"
    if not text or not path.is_file():
        raise ProblemError(f"unknown robot {text!r}; known robots: {known} (or a path to a "
                           "spec .json, see docs/robots.md)")
    return path


def _resolve_xml(ref: str, folder: Path, where: str) -> Path:
    if ref.startswith("brax:"):
        found = importlib.util.find_spec("brax")
        if found is None or not found.submodule_search_locations:
            raise ProblemError(f"{where}: xml {ref!r} is an asset of the brax package; "
                               "`pip install brax`")
        return Path(list(found.submodule_search_locations)[0]) / ref.removeprefix("brax:")
    path = (folder / ref).resolve()
    if not path.is_file():
        raise ProblemError(f"{where}: xml: {path} does not exist (the path is relative to the "
                           "spec's folder)")
    return path


def _xml_files(xml: Path) -> list[Path]:
    """The MJCF file and the files it ``<include>``s (recursively), in reading order."""
    out: list[Path] = []
    todo = [xml]
    while todo:
        path = todo.pop(0)
        if path in out or not path.is_file():
            continue
        out.append(path)
        text = path.read_text(errors="replace")
        todo += [path.parent / m for m in re.findall(r"<include\s+file=\"([^\"]+)\"", text)]
    return out


def spec_digest(spec_file: Path, xml: Path) -> str:
    """sha256 over the spec file and the MJCF with its included files: a checkpoint records it
    and ``eaco resume`` refuses a spec that changed since."""
    h = hashlib.sha256(spec_file.read_bytes())
    for path in _xml_files(xml):
        h.update(b"\0" + path.read_bytes())
    return h.hexdigest()


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


# --------------------------------------------------------------------------- reading a spec
def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _need(raw: dict[str, Any], key: str, kind: str, where: str) -> Any:
    """``raw[key]`` checked against ``kind`` ("str", "number", "names", "numbers", "object")."""
    if key not in raw:
        raise ProblemError(f"{where}: field '{key}' is missing (see docs/robots.md)")
    return _typed(raw[key], key, kind, where)


def _typed(v: Any, key: str, kind: str, where: str) -> Any:
    ok = {"str": lambda: isinstance(v, str) and v != "",
          "number": lambda: _is_number(v),
          "names": lambda: isinstance(v, list) and bool(v) and all(
              isinstance(x, str) and x for x in v),
          "numbers": lambda: isinstance(v, list) and all(_is_number(x) for x in v),
          "object": lambda: isinstance(v, dict)}[kind]()
    if not ok:
        wanted = {"str": "a non-empty string", "number": "a finite number",
                  "names": "a non-empty list of names", "numbers": "a list of numbers",
                  "object": "an object"}[kind]
        raise ProblemError(f"{where}: field '{key}' must be {wanted}, got {v!r:.60}")
    return v


def _read_raw(path: Path) -> dict[str, Any]:
    try:
        raw = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as err:
        raise ProblemError(f"robot spec {path}: cannot read it ({err})") from None
    except json.JSONDecodeError as err:
        raise ProblemError(f"robot spec {path}: not valid JSON ({err})") from None
    if not isinstance(raw, dict):
        raise ProblemError(f"robot spec {path}: must be a JSON object of fields "
                           "(see docs/robots.md)")
    return raw


def _solver(raw: dict[str, Any], where: str) -> dict[str, tuple[tuple[str, float], ...]]:
    solver = _need(raw, "solver", "object", where)
    out = {}
    for accuracy in ("fast", "accurate"):
        block = _need(solver, accuracy, "object", f"{where}: solver")
        for key in ("timestep", "iterations", "ls_iterations"):
            v = _need(block, key, "number", f"{where}: solver.{accuracy}")
            if v <= 0 or (key != "timestep" and int(v) != v):
                raise ProblemError(f"{where}: solver.{accuracy}.{key} must be a positive "
                                   f"{'number' if key == 'timestep' else 'integer'}, got {v}")
        if "tolerance" in block:
            _need(block, "tolerance", "number", f"{where}: solver.{accuracy}")
        out[accuracy] = tuple(sorted(block.items()))
    return out


def _joint_limits(model, names: list[str], where: str) -> tuple[list[float], list[float]]:
    """Each joint's range; an unlimited joint takes its actuator's ctrlrange."""
    import mujoco

    lower, upper = [], []
    for i, jn in enumerate(names):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, jn)
        if jid < 0:
            raise ProblemError(f"{where}: joint_names[{i}] {jn!r} is not a joint of the MJCF")
        if int(model.jnt_type[jid]) not in (int(mujoco.mjtJoint.mjJNT_HINGE),
                                            int(mujoco.mjtJoint.mjJNT_SLIDE)):
            raise ProblemError(f"{where}: joint_names[{i}] {jn!r} is not a hinge or slide joint")
        acts = [a for a in range(model.nu) if int(model.actuator_trntype[a]) ==
                int(mujoco.mjtTrn.mjTRN_JOINT) and model.actuator_trnid[a, 0] == jid]
        if not acts:
            raise ProblemError(f"{where}: joint_names[{i}] {jn!r}: no actuator of the MJCF "
                               "drives this joint (add a <position> or <motor> for it)")
        if model.jnt_limited[jid]:
            lo, hi = model.jnt_range[jid]
        elif model.actuator_ctrllimited[acts[0]]:
            lo, hi = model.actuator_ctrlrange[acts[0]]
        else:
            raise ProblemError(f"{where}: joint_names[{i}] {jn!r} has neither a range nor an "
                               "actuator ctrlrange in the MJCF; give it range=\"lo hi\"")
        lower.append(float(lo))
        upper.append(float(hi))
    return lower, upper


def _check_model(model, raw: dict[str, Any], names: list[str], where: str) -> None:
    """The spec's names exist in the MJCF, the actuators follow joint_names, the root is free."""
    import mujoco

    def exists(kind, name):
        return mujoco.mj_name2id(model, kind, name) >= 0

    if model.njnt == 0 or int(model.jnt_type[0]) != int(mujoco.mjtJoint.mjJNT_FREE):
        raise ProblemError(f"{where}: the MJCF's first joint must be a free joint (the "
                           "floating base: <freejoint/> in the torso body)")
    if not exists(mujoco.mjtObj.mjOBJ_GEOM, "floor"):
        raise ProblemError(f"{where}: the MJCF has no geom named 'floor' (add <geom "
                           "name=\"floor\" type=\"plane\" size=\"0 0 0.05\"/> to its worldbody)")
    order = [model.joint(model.actuator_trnid[a, 0]).name for a in range(model.nu)]
    if order != names:
        extra = [n for n in order if n not in names]
        hint = (f"the MJCF has actuators for joints not in joint_names: {extra}" if extra else
                f"list them in the MJCF's actuator order: {order}")
        raise ProblemError(f"{where}: joint_names must match the MJCF's actuators; {hint}")
    if not exists(mujoco.mjtObj.mjOBJ_BODY, raw["torso_body"]):
        raise ProblemError(f"{where}: torso_body {raw['torso_body']!r} is not a body of the MJCF")
    site = raw.get("torso_site")
    if site is not None and (not isinstance(site, str) or
                             not exists(mujoco.mjtObj.mjOBJ_SITE, site)):
        raise ProblemError(f"{where}: torso_site {site!r} is not a site of the MJCF (or null)")
    for i, g in enumerate(raw["foot_geoms"]):
        if not exists(mujoco.mjtObj.mjOBJ_GEOM, g):
            raise ProblemError(f"{where}: foot_geoms[{i}] {g!r} is not a geom of the MJCF")
    for i, f in enumerate(raw.get("feet", [])):
        if not (exists(mujoco.mjtObj.mjOBJ_BODY, f) or exists(mujoco.mjtObj.mjOBJ_SITE, f)):
            raise ProblemError(f"{where}: feet[{i}] {f!r} is not a body or site of the MJCF")


def _check_stance(model, spec: RobotSpec, where: str) -> None:
    """In the standing pose every foot hangs below its hip (the leg's first body below the
    torso): a spec with the wrong pose, sign or foot otherwise walks upside down."""
    import mujoco

    data = mujoco.MjData(model)
    data.qpos[:] = stand_qpos(spec, model)
    mujoco.mj_kinematics(model, data)
    torso = model.body(spec.torso_body).id
    for i, g in enumerate(spec.foot_geoms):
        gid = model.geom(g).id
        body = int(model.geom_bodyid[gid])
        while body != 0 and model.body_parentid[body] != torso:
            body = int(model.body_parentid[body])
        if body == 0 or body == torso:
            raise ProblemError(f"{where}: foot_geoms[{i}] {g!r} is not on a leg below torso_body "
                               f"{spec.torso_body!r}")
        foot_z, hip_z = float(data.geom_xpos[gid, 2]), float(data.xpos[body, 2])
        if foot_z >= hip_z - 1e-3:
            raise ProblemError(
                f"{where}: foot_geoms[{i}] {g!r} is not below its hip (body "
                f"{model.body(body).name!r}) in the standing pose: foot z {foot_z:.3f} m, hip z "
                f"{hip_z:.3f} m; check stand_ctrl and stand_root")


def load_robot(robot: str | Path) -> RobotSpec:
    """The checked :class:`RobotSpec` of a shipped robot (``"nao"``, ``"ant"``, ...) or of a
    spec file at any path; a bad spec is one ProblemError line naming the field."""
    path = spec_path(robot)
    where = f"robot spec {path}"
    raw = _read_raw(path)
    name = _need(raw, "name", "str", where)
    xml = _resolve_xml(_need(raw, "xml", "str", where), path.parent, where)
    gait = _need(raw, "gait", "str", where)
    if gait not in GAIT_KINDS:
        raise ProblemError(f"{where}: gait {gait!r} is not one of {', '.join(GAIT_KINDS)}")
    names = list(_need(raw, "joint_names", "names", where))
    stand = _need(raw, "stand_ctrl", "numbers", where)
    if len(stand) != len(names):
        raise ProblemError(f"{where}: stand_ctrl has {len(stand)} values for {len(names)} "
                           "joint_names")
    root = _need(raw, "stand_root", "numbers", where)
    if len(root) != 7 or not any(root[3:]):
        raise ProblemError(f"{where}: stand_root must be 7 numbers: x y z and a non-zero "
                           "quaternion w x y z")
    control_dt = _need(raw, "control_dt", "number", where)
    solver = _solver(raw, where)
    for accuracy, opts in solver.items():
        step = dict(opts)["timestep"]
        if control_dt <= 0 or abs(control_dt / step - round(control_dt / step)) > 1e-6:
            raise ProblemError(f"{where}: control_dt {control_dt} must be a positive multiple of "
                               f"solver.{accuracy}.timestep {step}")
    _need(raw, "torso_body", "str", where)
    _need(raw, "foot_geoms", "names", where)
    feet = _typed(raw["feet"], "feet", "names", where) if "feet" in raw else []
    arms = _arm_swing_joints(raw, names, gait, where)
    numbers = {k: float(_need(raw, k, "number", where))
               for k in ("nominal_torso_height", "fall_height", "fall_tilt_deg")}
    if not 0.0 < numbers["fall_tilt_deg"] <= 180.0 or numbers["nominal_torso_height"] <= 0:
        raise ProblemError(f"{where}: fall_tilt_deg must be in (0, 180] and "
                           "nominal_torso_height > 0")
    geometry = _typed(raw.get("geometry", {}), "geometry", "object", where)
    for k, v in geometry.items():
        _typed(v, f"geometry.{k}", "number", where)
    servo = _typed(raw.get("position_servo", {}), "position_servo", "object", where)
    for k in ("kp", "forcerange") if servo else ():
        if not _is_number(servo.get(k)) or servo[k] <= 0:
            raise ProblemError(f"{where}: position_servo.{k} must be a positive number")
    import mujoco

    try:
        model = mujoco.MjModel.from_xml_path(str(xml))
    except ValueError as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else "compile error"
        raise ProblemError(f"{where}: xml: MuJoCo cannot load {xml}: {first}") from None
    lower, upper = _joint_limits(model, names, where)
    _check_model(model, raw, names, where)
    for i, (v, lo, hi) in enumerate(zip(stand, lower, upper, strict=True)):
        if not lo - 1e-6 <= v <= hi + 1e-6:
            raise ProblemError(f"{where}: stand_ctrl[{i}] = {v} is outside joint {names[i]!r}'s "
                               f"range [{lo:.4g}, {hi:.4g}]")
    if servo:
        force = [float(servo["forcerange"])] * len(names)
    else:
        force = [float(max(abs(model.actuator_forcerange[a]))) if model.actuator_forcelimited[a]
                 else math.inf for a in range(model.nu)]
    spec = RobotSpec(
        name=name,
        xml_path=str(xml),
        gait=gait,
        joint_names=tuple(names),
        stand_ctrl=tuple(float(v) for v in stand),
        stand_root=tuple(float(v) for v in root),
        joint_lower=tuple(lower),
        joint_upper=tuple(upper),
        control_dt=float(control_dt),
        solver_fast=solver["fast"],
        solver_accurate=solver["accurate"],
        torso_body=raw["torso_body"],
        foot_geoms=tuple(raw["foot_geoms"]),
        nominal_torso_height=numbers["nominal_torso_height"],
        fall_height=numbers["fall_height"],
        fall_tilt_deg=numbers["fall_tilt_deg"],
        geometry=tuple(sorted((k, float(v)) for k, v in geometry.items())),
        position_servo=tuple(sorted((k, float(v)) for k, v in servo.items())),
        force_limit=tuple(force),
        source=str(path),
        digest=spec_digest(path, xml),
        feet=tuple(feet),
        arm_swing_joints=arms,
        **_motor_fields(raw, where),
    )
    _check_stance(model, spec, where)
    return spec


def _arm_swing_joints(raw: dict[str, Any], names: list[str], gait: str,
                      where: str) -> tuple[str, ...]:
    """The optional ``arm_swing_joints``: a biped's left and right shoulder-pitch joints, which
    the walk engine swings against the legs (none: the arms hold their standing pose)."""
    if "arm_swing_joints" not in raw:
        return ()
    arms = _typed(raw["arm_swing_joints"], "arm_swing_joints", "names", where)
    if gait != "biped" or len(arms) != 2:
        raise ProblemError(f"{where}: arm_swing_joints must be two joint names, left then "
                           "right, on a biped")
    for i, j in enumerate(arms):
        if j not in names:
            raise ProblemError(f"{where}: arm_swing_joints[{i}] {j!r} is not in joint_names")
    return tuple(arms)


def _motor_fields(raw: dict[str, Any], where: str) -> dict[str, Any]:
    if "motors" not in raw:
        return {}
    try:
        mc = motor_constants(raw, raw["joint_names"])
        return dict(
            stall_torque=tuple(mc["stall"]),
            no_load_speed=tuple(mc["no_load_speed"]),
            nominal_torque=tuple(mc["nominal"]),
            coupled_joints=tuple(tuple(p) for p in raw.get("coupled_joints", [])),
            motor_tolerances=tuple(sorted(raw["motors"].get("tolerances", {}).items())),
        )
    except (KeyError, TypeError, ValueError, ZeroDivisionError) as err:
        raise ProblemError(f"{where}: motors: {err} (see docs/robots.md)") from None


# --------------------------------------------------------------------------- models
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
