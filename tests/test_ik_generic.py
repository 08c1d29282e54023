"""Generic leg IK: chain FK equals MuJoCo's, IK round trip, joint limits, agreement with the
NAO's analytic IK on the stored gait, vmap/jit shapes, the walk engines that use it."""

import json
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.gait import ik_generic as g
from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.ik import leg_ik
from eaco_jax.gait.legs import leg_set
from eaco_jax.gait.robot import load_model, load_robot

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


@pytest.fixture(scope="module")
def model(nao):
    return load_model(nao)


def _mujoco_foot(model, names, q, foot_body, site=None):
    """Foot pose relative to the torso by MuJoCo's own kinematics (torso tilted, so frames
    matter)."""
    data = mujoco.MjData(model)
    data.qpos[:3] = [0.1, -0.2, 0.3]
    data.qpos[3:7] = np.array([0.9, 0.1, -0.2, 0.3]) / np.linalg.norm([0.9, 0.1, -0.2, 0.3])
    for n, v in zip(names, q, strict=True):
        data.qpos[model.joint(n).qposadr[0]] = v
    mujoco.mj_kinematics(model, data)
    t = model.body("torso").id
    rt = data.xmat[t].reshape(3, 3)
    if site is None:
        pos, rot = data.xpos[foot_body], data.xmat[foot_body].reshape(3, 3)
    else:
        pos, rot = data.site_xpos[site], data.site_xmat[site].reshape(3, 3)
    return rt.T @ (pos - data.xpos[t]), rt.T @ rot


@pytest.mark.parametrize("foot", ["l_foot", "r_sole_site"])
def test_chain_fk_equals_mujoco(model, foot):
    chain, names = g.extract_chain(model, "torso", foot)
    assert len(names) == 6 and names[0][1:] == "HipYawPitch"
    rng = np.random.default_rng(0)
    site = model.site(foot).id if foot.endswith("site") else None
    body = None if site is not None else model.body(foot).id
    for _ in range(5):
        q = rng.uniform(chain.lower, chain.upper)
        pos, rot = g.fk(chain, jnp.asarray(q, jnp.float32))
        ref_pos, ref_rot = _mujoco_foot(model, names, q, body, site)
        np.testing.assert_allclose(pos, ref_pos, atol=2e-6)
        np.testing.assert_allclose(rot, ref_rot, atol=2e-6)


def test_round_trip_random_reachable_targets(model, nao):
    """Targets made by FK from random angles in the walking range are reached within 1 mm (and
    the sole's orientation within 1 mrad) from the standing pose, jitted and vmapped."""
    chain, names = g.extract_chain(model, "torso", "l_foot")
    stand = jnp.asarray([nao.stand_ctrl[nao.joint_names.index(n)] for n in names])
    rng = np.random.default_rng(1)
    q_true = stand + rng.uniform(-0.35, 0.35, (128, 6)).astype(np.float32)
    q_true = jnp.clip(q_true, chain.lower, chain.upper)
    fk = jax.jit(jax.vmap(lambda q: g.fk(chain, q)))
    pos, rot = fk(q_true)
    q, err = jax.jit(jax.vmap(lambda p, r: g.solve(chain, p, stand, r)))(pos, rot)
    assert q.shape == (128, 6) and err.shape == (128,)
    got_pos, got_rot = fk(q)
    assert float(jnp.max(jnp.linalg.norm(got_pos - pos, axis=-1))) < 1e-3
    assert float(jnp.max(err)) < 1e-3
    assert float(jnp.max(jnp.abs(got_rot - rot))) < 1e-3
    # position only: a 3-task solve of the same targets
    q3, err3 = jax.jit(jax.vmap(lambda p: g.solve(chain, p, stand)))(pos)
    assert float(jnp.max(err3)) < 1e-3


def test_joint_limits_respected(model, nao):
    """Targets beyond reach or needing angles past the limits give angles inside the limits."""
    chain, names = g.extract_chain(model, "torso", "l_foot")
    stand = jnp.asarray([nao.stand_ctrl[nao.joint_names.index(n)] for n in names])
    rng = np.random.default_rng(2)
    targets = jnp.asarray(rng.uniform([-0.3, -0.3, -0.5], [0.3, 0.3, 0.0], (64, 3)), jnp.float32)
    q, err = jax.jit(jax.vmap(lambda p: g.solve(chain, p, stand, iterations=20)))(targets)
    assert np.all(np.isfinite(q))
    assert np.all(q >= chain.lower) and np.all(q <= chain.upper)
    assert float(jnp.max(err)) > 0.05  # some of these were out of reach


def _stored_gait_cycle(nao, periods=2.0):
    gait = json.loads((ROOT / "experiments/results/nao_best_gait.json").read_text())
    v = jnp.asarray(gait["vector"], jnp.float32)
    # one ramp second, then whole periods of the steady cycle
    t = jnp.arange(0.0, we.RAMP_TIME + periods * float(gait["params"]["period"]), nao.control_dt)
    return jax.jit(jax.vmap(lambda tt: we.biped_feet(v, tt, nao)))(t)


def test_nao_agreement_on_the_stored_gait(nao, model):
    """On the stored gait's ankle targets the generic IK's ankles are where the analytic IK's
    are, within 1 mm, and its joint angles within 1 mrad (vmapped over legs and time)."""
    found = [g.extract_chain(model, "torso", f) for f in ("l_foot", "r_foot")]
    chains = g.stack_chains([c for c, _ in found])
    stand = jnp.asarray([[nao.stand_ctrl[nao.joint_names.index(n)] for n in names]
                         for _, names in found])
    hip = jnp.stack([c.offset_pos[0] for c, _ in found])  # hip joint point, torso frame
    feet = _stored_gait_cycle(nao)
    foot_h, h0 = nao.geom("foot_height"), nao.geom("stand_hip_height")
    ankle = feet.delta + jnp.array([0.0, 0.0, -(h0 - foot_h)])  # (T, 2, 3) relative to the hip
    q_ref = leg_ik(ankle, feet.yaw, nao.geom("thigh"), nao.geom("tibia"))  # (T, 2, 6)
    q_ref = q_ref.at[:, 1, 0].multiply(-1.0)  # RHipYawPitch turns about -z
    rot = jax.vmap(jax.vmap(we._rot_z))(feet.yaw)

    def per_leg(c, p, q0, r):
        return g.solve(c, p, q0, r)[0]

    q = jax.jit(jax.vmap(jax.vmap(per_leg), in_axes=(None, 0, None, 0)))(
        chains, hip + ankle, stand, rot)
    assert q.shape == q_ref.shape
    fk = jax.jit(jax.vmap(jax.vmap(lambda c, qq: g.fk(c, qq)[0]), in_axes=(None, 0)))
    gap = jnp.linalg.norm(fk(chains, q) - fk(chains, q_ref), axis=-1)
    assert float(jnp.max(gap)) < 1e-3
    assert float(jnp.max(jnp.abs(q - q_ref))) < 1e-3


def test_analytic_reference_is_what_the_engine_feeds(nao):
    """The agreement test's reference targets are the analytic engine's own: its leg angles are
    leg_ik of these targets plus the compensations."""
    gait = json.loads((ROOT / "experiments/results/nao_best_gait.json").read_text())
    v = jnp.asarray(gait["vector"], jnp.float32)
    t = jnp.float32(1.3)
    feet = we.biped_feet(v, t, nao)
    ankle = feet.delta[0] + jnp.array([0.0, 0.0, -(0.22 - nao.geom("foot_height"))])
    q = leg_ik(ankle, feet.yaw[0], nao.geom("thigh"), nao.geom("tibia"))
    out = we.joint_targets(v, t, nao, ik="analytic")
    i = nao.joint_names.index("LKneePitch")
    assert float(out[i]) == pytest.approx(float(q[3]), abs=1e-5)
    i = nao.joint_names.index("LHipPitch")
    assert float(out[i]) == pytest.approx(float(q[2] + feet.offsets[0, 1]), abs=1e-5)


def test_engine_generic_matches_analytic_on_nao(nao):
    """ik='generic' on the NAO gives the analytic engine's joint targets within 1 mrad over the
    stored gait's first two seconds (the standing foot is 10 um off the hip's vertical)."""
    gait = json.loads((ROOT / "experiments/results/nao_best_gait.json").read_text())
    v = jnp.asarray(gait["vector"], jnp.float32)
    a = jax.jit(lambda p: we.control_sequence(p, 100, nao, ik="analytic"))(v)
    b = jax.jit(lambda p: we.control_sequence(p, 100, nao, ik="generic"))(v)
    assert b.shape == (100, nao.nu)
    np.testing.assert_allclose(a, b, atol=1e-3)
    assert we.uses_analytic_ik(nao) and not we.uses_analytic_ik(nao, "generic")


def test_analytic_without_geometry_is_refused(tmp_path):
    raw = json.loads((ROOT / "robots/nao.json").read_text())
    raw.pop("geometry")
    raw["xml"] = str(ROOT / "robots/nao.xml")
    path = tmp_path / "nao_nogeo.json"
    path.write_text(json.dumps(raw))
    spec = load_robot(path)
    assert not we.uses_analytic_ik(spec)  # auto: the generic IK
    with pytest.raises(ConfigError, match="use ik=.generic."):
        we.uses_analytic_ik(spec, "analytic")
    lo, hi = we.bounds(spec)  # lengths scale with the measured standing hip height
    h = leg_set(spec).stand_height
    i = we.PARAM_NAMES.index("hip_height")
    assert lo[i] == pytest.approx(we.LOWER[i] * h / we.REF_HIP_HEIGHT, rel=1e-5)
    q = we.joint_targets(jnp.asarray((lo + hi) / 2), jnp.float32(0.0), spec)
    np.testing.assert_allclose(q, np.asarray(spec.stand_ctrl), atol=2e-3)


QUAD_XML = """<mujoco model="toy_quadruped">
  <compiler angle="radian"/>
  <option timestep="0.004"/>
  <default><joint type="hinge" limited="true" damping="0.5"/>
    <geom type="capsule" size="0.015" density="500"/></default>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="trunk" pos="0 0 0.3">
      <freejoint name="root"/>
      <geom type="box" size="0.18 0.07 0.04"/>
      {legs}
    </body>
  </worldbody>
  <actuator>{acts}</actuator>
</mujoco>"""
LEG = """<body name="{n}_hip" pos="{x} {y} 0">
        <joint name="{n}_abd" axis="1 0 0" range="-0.8 0.8"/>
        <geom type="sphere" size="0.03"/>
        <body name="{n}_thigh" pos="0 {o} 0" quat="0.9998 0 0.02 0">
          <joint name="{n}_hip" axis="0 1 0" range="-1.5 3.0"/>
          <geom fromto="0 0 0 0 0 -0.2"/>
          <body name="{n}_calf" pos="0 0 -0.2">
            <joint name="{n}_knee" axis="0 1 0" range="-2.7 -0.9"/>
            <geom fromto="0 0 0 0 0 -0.2"/>
            <geom name="{n}_foot" type="sphere" size="0.02" pos="0 0 -0.2"/>
          </body>
        </body>
      </body>"""


@pytest.fixture(scope="module")
def quad(tmp_path_factory):
    """A small three-joint-leg quadruped (Go1-like layout) written as MJCF + spec."""
    folder = tmp_path_factory.mktemp("quad")
    legs, acts, names = [], [], []
    for n, x, y in (("FR", 0.18, -0.05), ("FL", 0.18, 0.05), ("RR", -0.18, -0.05),
                    ("RL", -0.18, 0.05)):
        legs.append(LEG.format(n=n, x=x, y=y, o=0.04 if y > 0 else -0.04))
        for j in ("abd", "hip", "knee"):
            names.append(f"{n}_{j}")
            acts.append(f'<position joint="{n}_{j}" kp="20" forcerange="-20 20"/>')
    (folder / "quad.xml").write_text(QUAD_XML.format(legs="\n".join(legs), acts="".join(acts)))
    spec = {
        "name": "toy_quad", "xml": "quad.xml", "gait": "quadruped", "joint_names": names,
        "stand_ctrl": [0.0, 0.8, -1.6] * 4, "stand_root": [0, 0, 0.3, 1, 0, 0, 0],
        "control_dt": 0.02,
        "solver": {"fast": {"timestep": 0.004, "iterations": 4, "ls_iterations": 6},
                   "accurate": {"timestep": 0.002, "iterations": 50, "ls_iterations": 20}},
        "torso_body": "trunk", "foot_geoms": [f"{n}_foot" for n in ("FR", "FL", "RR", "RL")],
        "nominal_torso_height": 0.28, "fall_height": 0.15, "fall_tilt_deg": 50.0,
    }
    (folder / "quad.json").write_text(json.dumps(spec))
    return load_robot(folder / "quad.json")


def test_quadruped_trot_uses_generic_ik(quad):
    legs = leg_set(quad)
    assert legs.feet == ("FR_calf", "FL_calf", "RR_calf", "RL_calf")
    assert legs.side.tolist() == [-1.0, 1.0, -1.0, 1.0]
    assert legs.front.tolist() == [1.0, 1.0, -1.0, -1.0]
    assert we.param_names(quad) == we.TROT_PARAM_NAMES
    lo, hi = we.bounds(quad)
    assert lo.shape == (8,) and np.all(lo < hi)
    p = dict(zip(we.TROT_PARAM_NAMES, (lo + hi) / 2, strict=True))
    p.update(step_length=0.1, body_height=legs.stand_height - 0.02, duty_ratio=0.5,
             period=0.4, foot_lift=0.05, stance_width=0.0, direction=0.0, body_pitch=0.0)
    v = jnp.asarray([p[n] for n in we.TROT_PARAM_NAMES], jnp.float32)
    t = jnp.arange(0.0, 2.0, quad.control_dt)
    q = jax.jit(jax.vmap(lambda tt: we.joint_targets(v, tt, quad)))(t)
    assert q.shape == (len(t), 12)
    np.testing.assert_allclose(q[0], np.asarray(quad.stand_ctrl), atol=1e-3)
    assert np.all(q >= np.asarray(quad.joint_lower) - 1e-6)
    # the feet follow the trot: FL and RR together, FR half a cycle apart; steady cycle
    chain = legs.chain
    for tt in (1.1, 1.3):  # FL mid-swing / mid-stance after the ramp
        qt = we.joint_targets(v, jnp.float32(tt), quad)
        feet = jax.vmap(lambda c, qq: g.fk(c, qq)[0])(chain, qt[legs.joint_index])
        dz = np.asarray(feet[:, 2] - legs.stand_pos[:, 2]) - 0.02  # body 2 cm lower
        lifted = dz > 0.01
        assert lifted[1] == lifted[2] and lifted[0] == lifted[3] and lifted[0] != lifted[1]
    # stance feet are at the commanded height below the hips (1 mm)
    qt = we.joint_targets(v, jnp.float32(1.1), quad)
    feet = jax.vmap(lambda c, qq: g.fk(c, qq)[0])(chain, qt[legs.joint_index])
    stance = np.asarray(feet[:, 2] - legs.stand_pos[:, 2]) - 0.02 < 0.01
    assert stance.sum() == 2
    np.testing.assert_allclose(np.asarray(legs.hip_pos[stance, 2] - feet[stance, 2]),
                               p["body_height"], atol=1e-3)


def test_bad_leg_chains_are_one_line(model):
    with pytest.raises(ProblemError, match="not below the torso"):
        g.extract_chain(model, "l_foot", "r_foot")
    with pytest.raises(ProblemError, match="neither a body nor a site"):
        g.extract_chain(model, "torso", "no_such_foot")
    with pytest.raises(ProblemError, match="different joint counts"):
        g.stack_chains([g.extract_chain(model, "torso", "l_foot")[0],
                        g.extract_chain(model, "torso", "l_tibia")[0]])
