"""Batched gait rollouts on MJX: a ``lax.scan`` over control steps of ``vmap(mjx.step)``.

Each control step sets the rollouts' position targets (the walk engine's output at
``t = k * control_dt``, precomputed for every ant) and runs ``substeps`` ``mjx.step`` calls holding
them (or, where the spec says so, :func:`eaco_jax.gait.motors.interpolates_targets`, moving them
linearly to the next control step's). Only the torso trace ``(B, T + 1, 7)`` (root position,
up axis and heading after each control step, row 0 = start) is kept, the same as the native
backend returns; ``record=True`` also returns ``qpos`` after each control step (for plots and
videos).

With ``worlds`` (:mod:`eaco_jax.gait.worlds`) every ant runs in each of the R worlds, rollout
``b = a * R + r``, all in one ``vmap``: the model is batched over the varied fields
(``in_axes`` 0 on them, ``None`` elsewhere), the targets get each world's latency and noise
inside the scan, the initial poses and pushes are per world. With ``quality`` the scan also
accumulates the energy and gait-quality terms of :mod:`eaco_jax.gait.quality` (the physics
substeps then run as a small ``scan`` that keeps joint positions and speeds); without it the
loop body holds nothing but physics.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.errors import ConfigError
from eaco_jax.gait import motors as mo
from eaco_jax.gait import quality as ql
from eaco_jax.gait import steer as st
from eaco_jax.gait.fitness import is_down
from eaco_jax.gait.mjx_import import quiet_mjx
from eaco_jax.gait.robot import RobotSpec
from eaco_jax.gait.rollout_native import (
    floor_normal,
    initial_state,
    native_model,
    nominal_motor,
    substeps,
    torque_model,
)
from eaco_jax.gait.walk_engine import stand_pose
from eaco_jax.gait.worlds import (
    VARIED_FIELDS,
    Worlds,
    actuated_dofs,
    couple_controls,
    delayed_at,
    friction_geom_ids,
    initial_qpos,
    model_fields,
    push_at,
    world_ctrl_at,
)

mjx = quiet_mjx()


IMPLS = ("jax", "warp")


@functools.lru_cache(maxsize=16)
def mjx_model(spec: RobotSpec, slope_deg: float, accuracy: str, impl: str = "jax",
              torque: bool = False) -> mjx.Model:
    """The MJX model for ``(robot, slope, accuracy)`` and implementation (``"jax"`` or
    ``"warp"``: MuJoCo Warp through MJX's FFI, CUDA only), cached (same MjModel as native;
    ``torque``: its direct-torque form, :func:`~eaco_jax.gait.rollout_native.torque_model`).

    Built with concrete arrays even when first called inside a jit trace: the cache outlives
    the trace, so a traced model would leak into the next one.
    """
    with jax.ensure_compile_time_eval():
        model = (torque_model if torque else native_model)(spec, slope_deg, accuracy)
        if impl == "jax":
            return mjx.put_model(model)
        return _warp_model(model)


#: Newton iterations on MuJoCo Warp, at least: the fast setting (4) leaves a walking robot
#: millimetres off the converged path within a second; 8 keep it on that path at the same steps
#: per second, since most worlds converge early (``experiments/warp_gait.py``, solver section)
WARP_ITERATIONS = 8


#: CUDA graph modes of MJX's Warp FFI (``warp.JaxCallableGraphMode``), chosen by the
#: environment variable ``EACO_WARP_GRAPH_MODE`` (unset: MJX's default on a GPU, ``warp``, which
#: replays a captured graph only for the buffer addresses it was captured with;
#: ``warp_staged`` replays it through staging buffers whatever the addresses)
WARP_GRAPH_MODES = ("warp", "warp_staged", "warp_staged_ex", "jax", "none")


def warp_graph_mode() -> str | None:
    """The graph mode ``EACO_WARP_GRAPH_MODE`` asks for (None: unset, MJX's default)."""
    import os

    mode = os.environ.get("EACO_WARP_GRAPH_MODE", "").strip().lower()
    if not mode:
        return None
    if mode not in WARP_GRAPH_MODES:
        raise ConfigError(f"EACO_WARP_GRAPH_MODE={mode!r} is not a Warp graph mode: use one of "
                          f"{', '.join(WARP_GRAPH_MODES)}, or unset it")
    return mode


def _warp_model(model):
    """MuJoCo Warp model: at least :data:`WARP_ITERATIONS` solver iterations, and no print
    when a world uses them all (a deliberate cap); buffer overflows still warn; the graph
    mode of :func:`warp_graph_mode` where one is set."""
    import copy

    from mujoco.mjx.third_party.mujoco_warp._src.types import OverflowType

    model = copy.copy(model)
    model.opt.iterations = max(int(model.opt.iterations), WARP_ITERATIONS)
    mode, extra = warp_graph_mode(), {}
    if mode is not None:
        import warp as wp

        extra["graph_mode"] = getattr(wp.JaxCallableGraphMode, mode.upper())
    mm = mjx.put_model(model, impl="warp", **extra)
    capped = int(getattr(OverflowType, "ITERATIONS", 0)) | int(
        getattr(OverflowType, "LS_ITERATIONS", 0))
    bits = int(OverflowType.ALL) & ~capped
    opt_impl = mm.opt._impl.replace(warn_overflow=bits)
    return mm.replace(opt=mm.opt.replace(_impl=opt_impl))


#: most contacts MuJoCo Warp's plane colliders write for one pair, by the other geom's type
#: (mjtGeom: 2 sphere, 3 capsule, 4 ellipsoid, 5 cylinder, 6 box, 7 mesh), read from its
#: ``collision_primitive.py`` (plane_sphere 1, plane_capsule 2, plane_ellipsoid 1,
#: plane_cylinder 4, plane_box 8 corners, plane_convex 4); other pairs: 8.
PLANE_CONTACTS = {2: 1, 3: 2, 4: 1, 5: 4, 6: 8, 7: 4}
PAIR_CONTACTS = 8


def contact_capacity(model) -> tuple[int, int]:
    """Per-world upper bounds ``(contacts, constraint rows)`` for MuJoCo Warp's fixed buffers.

    Contacts: every geom that can touch the floor plane (contype/conaffinity) with the most
    contacts its plane collider writes (:data:`PLANE_CONTACTS`: a sphere 1, a box 8), plus
    :data:`PAIR_CONTACTS` per pair of robot geoms that can collide. Rows: each contact's
    pyramidal friction rows (2 (condim - 1), at least 1), equality rows, every limited joint
    and friction-loss dof. Exact bounds, not estimates: the buffers cost time in proportion
    to their size (MuJoCo Warp launches its constraint kernels over ``njmax`` rows), so they
    are no larger than the model can fill (the NAO: 8 sole spheres -> 8 contacts, 57 rows;
    native MuJoCo over random gaits, falls included, stays within both).
    """
    import numpy as np_

    ctype, caff = model.geom_contype, model.geom_conaffinity
    plane = model.geom_type == 0
    collides = (ctype | caff) > 0
    floor = np_.flatnonzero(plane & collides)
    robot = np_.flatnonzero(~plane & collides)
    contacts = 0
    for f in floor:
        touches = ((ctype[robot] & caff[f]) | (ctype[f] & caff[robot])) > 0
        contacts += sum(PLANE_CONTACTS.get(int(model.geom_type[g]), PAIR_CONTACTS)
                        for g in robot[touches])
    if len(robot) > 1:
        cross = (ctype[robot][:, None] & caff[robot][None, :]) | (
            ctype[robot][None, :] & caff[robot][:, None])
        contacts += PAIR_CONTACTS * int(np_.sum(np_.triu(cross > 0, 1)))
    contacts += PAIR_CONTACTS * model.npair
    condim = int(np_.max(model.geom_condim)) if model.ngeom else 3
    rows = contacts * max(1, 2 * (condim - 1))
    eq_rows = {0: 3, 1: 6, 2: 1, 3: 1}  # connect, weld, joint, tendon
    rows += sum(eq_rows.get(int(t), 6) for t in model.eq_type)
    rows += int(np_.sum(model.jnt_limited)) + int(np_.sum(model.dof_frictionloss > 0))
    return int(contacts), int(rows)


def _warp_overflow(nacon, nefc, naconmax: int, njmax: int) -> None:
    """Host side of the overflow check: one line on stderr, never silent."""
    import sys

    nacon, nefc = int(np.max(nacon)), int(np.max(nefc))
    if nacon > naconmax or nefc > njmax:
        print(f"warning: MuJoCo Warp buffers overflowed (contacts or broadphase pairs {nacon} > "
              f"{naconmax} or "
              f"constraint rows {nefc} > {njmax} per world): contacts were dropped; raise "
              "eaco_jax.gait.rollout_mjx.CAPACITY_MARGIN", file=sys.stderr)


def warp_buffers(model, worlds: int, copies: int = 1) -> tuple[int, int]:
    """MuJoCo Warp's ``(naconmax, njmax)`` for one call of ``worlds`` worlds run ``copies``
    times under an outer vmap: the contact buffer is one for the whole flattened batch
    (every world of every copy), the constraint rows are per world."""
    per_world, rows = contact_capacity(model)
    return (int(CAPACITY_MARGIN * per_world * worlds * max(1, int(copies))),
            int(CAPACITY_MARGIN * rows))


def warp_pairs(d) -> jax.Array:
    """The contact buffer's demand in MuJoCo Warp data ``d``: the larger of the contacts and
    the broadphase's candidate pairs, both held in ``naconmax`` slots. The pairs overflow
    first (then the contacts stay within the buffer and only the pairs show the loss)."""
    return jnp.maximum(jnp.max(d._impl.nacon), jnp.max(d._impl.ncollision))


#: Warp buffers are sized at this multiple of :func:`contact_capacity` (an exact upper bound,
#: so 1; raised only to compare, e.g. in experiments/warp_gait.py ``--capacity-scale``)
CAPACITY_MARGIN = 1.0


def root_trace(qpos: jax.Array) -> jax.Array:
    """``qpos`` (..., nq) -> torso position, up (z) axis and heading (yaw of the torso's x axis,
    rad) ``(..., 7)`` from the free joint."""
    w, x, y, z = (qpos[..., i] for i in range(3, 7))
    up = jnp.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], -1)
    yaw = jnp.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return jnp.concatenate([qpos[..., :3], up, yaw[..., None]], -1)


def _world_model(mm: mjx.Model, fields: dict[str, jax.Array], world_of: jax.Array):
    """``mm`` with the varied fields batched per rollout, and the matching ``in_axes``."""
    batched = mm.tree_replace({k: jnp.take(v, world_of, axis=0) for k, v in fields.items()})
    axes = jax.tree.map(lambda _: None, mm).tree_replace({k: 0 for k in fields})
    return batched, axes


def mjx_rollout(
    controls: jax.Array,
    spec: RobotSpec,
    slope_deg: float = 0.0,
    accuracy: str = "fast",
    worlds: Worlds | None = None,
    quality: bool = False,
    record: bool = False,
    impl: str = "jax",
    limits: bool | None = None,
    trace_every: int = 0,
    interpolate: bool | None = None,
    steer: st.SteerInputs | None = None,
    copies: int = 1,
) -> dict[str, jax.Array]:
    """Roll out the ants' targets ``controls`` ``(A, T, nu)`` on MJX (in R worlds if given).

    Returns ``trace`` ``(B, T + 1, 7)``, ``qpos`` ``(B, T + 1, nq)`` with ``record`` and the
    quality accumulators ``acc`` with ``quality``; ``B = A * R`` (R = 1 without worlds).
    ``limits`` (default: the spec's): the motor limits in the physics. ``trace_every`` (with
    ``quality``): sample the motors' temperatures every that many control steps, inside the
    scan (no per-step history is kept). ``interpolate`` (default: the spec's,
    :func:`~eaco_jax.gait.motors.interpolates_targets`): the targets move linearly from one
    control step's to the next over its physics steps instead of being held.
    ``steer`` (:mod:`eaco_jax.gait.steer`): the heading controller corrects the targets at
    every control step from the torso's pose.
    ``impl="warp"`` runs MuJoCo Warp (CUDA) with contact and constraint buffers sized from the
    model and the batch (:func:`contact_capacity`); an overflow is reported on stderr.
    ``copies``: how many vmapped copies of this rollout an outer ``jax.vmap`` runs (MuJoCo
    Warp flattens them into one batch sharing one contact buffer, so it holds them all).
    Traceable: call it inside jit / scan.
    """
    if impl not in IMPLS:
        raise ValueError(f"impl must be one of {IMPLS}, got {impl!r}")
    model = native_model(spec, float(slope_deg), accuracy)
    k = substeps(spec, model)
    limits = mo.physics_limits(spec) if limits is None else bool(limits)
    if limits and mo.motor_model(spec) is None:
        raise ValueError(f"robot {spec.name}: no electrical motor data, no limits to apply")
    interpolate = mo.interpolates_targets(spec) if interpolate is None else bool(interpolate)
    need_motor = quality or limits
    mm = mjx_model(spec, float(slope_deg), accuracy, impl, limits)
    a, n_steps, nu = controls.shape
    controls = controls.astype(jnp.float32)
    qpos0 = jnp.asarray(initial_state(spec, model, slope_deg)[1 : 1 + model.nq], jnp.float32)
    ctrl0 = jnp.asarray(stand_pose(spec, slope_deg), jnp.float32)
    r = 1 if worlds is None else worlds.size
    nb = a * r
    world_of = jnp.arange(nb) % r
    dofs = np.asarray(actuated_dofs(model, spec))
    warp = impl == "warp"
    if warp:
        naconmax, njmax = warp_buffers(model, nb, copies)
        dw = mjx.make_data(model, impl="warp", naconmax=naconmax, njmax=njmax)  # buffers only
    if worlds is None and warp:
        step = jax.vmap(lambda d: mjx.step(mm, d))
        d0 = dw.replace(ctrl=ctrl0)
        data = jax.vmap(lambda q: mjx.forward(mm, d0.replace(qpos=q)))(
            jnp.broadcast_to(qpos0, (nb,) + qpos0.shape))
        motor = nominal_motor(spec, model) if need_motor else None
        mp = None if motor is None else ql.MotorParams(
            *(jnp.broadcast_to(jnp.asarray(x, jnp.float32), (nb, nu))[:, None] for x in motor))
    elif worlds is None:
        step = jax.vmap(lambda d: mjx.step(mm, d))
        data = mjx.forward(mm, mjx.make_data(mm).replace(qpos=qpos0, ctrl=ctrl0))
        data = jax.tree.map(lambda x: jnp.broadcast_to(x, (nb,) + x.shape), data)
        motor = nominal_motor(spec, model) if need_motor else None
        mp = None if motor is None else ql.MotorParams(
            *(jnp.broadcast_to(jnp.asarray(x, jnp.float32), (nb, nu))[:, None] for x in motor))
    else:
        base = {f: jnp.asarray(getattr(model, f), jnp.float32) for f in VARIED_FIELDS}
        fields = model_fields(base, worlds, friction_geom_ids(model, spec), dofs)
        servo_fields = fields
        if limits:
            fields = _torque_fields(fields, dofs, mo.friction_share(spec))
        mmb, axes = _world_model(mm, fields, world_of)
        step = jax.vmap(mjx.step, in_axes=(axes, 0))
        qadr = np.array([model.joint(n).qposadr[0] for n in spec.joint_names])
        qinit = initial_qpos(qpos0, worlds, qadr, np.asarray(spec.joint_lower, np.float32),
                             np.asarray(spec.joint_upper, np.float32))
        d0 = (dw if warp else mjx.make_data(mm)).replace(ctrl=ctrl0)
        data = jax.vmap(lambda m_, q: mjx.forward(m_, d0.replace(qpos=q)), in_axes=(axes, 0))(
            mmb, jnp.take(qinit, world_of, axis=0))
        mp = None
        if need_motor:
            motor = ql.motor_params(servo_fields, spec, dofs, model.actuator_ctrlrange,
                                    worlds.stall_scale, worlds.speed_scale)
            mp = ql.MotorParams(*(jnp.take(jnp.broadcast_to(jnp.asarray(x, jnp.float32),
                                                            (r, nu)), world_of, axis=0)[:, None]
                                  for x in motor))
    sole_adr = None
    el = ql.electrics(spec, spec.control_dt, k, n_steps, trace_every) if quality else None
    if quality:
        sole_adr = np.concatenate([model.sensor_adr[model.sensor(n).id] + np.arange(3)
                                   for n in ql.sole_sensor_names(spec)])
        normal = floor_normal(slope_deg)
        radius = float(model.geom_size[model.geom(spec.foot_geoms[0]).id, 0])
    qadr_all = np.array([model.joint(n).qposadr[0] for n in spec.joint_names])
    dt = float(model.opt.timestep)

    def targets(t):
        if worlds is None:
            return couple_controls(controls[:, t], spec)
        return world_ctrl_at(controls, t, worlds, spec).reshape(nb, nu)

    if steer is not None:
        dctrl = jnp.asarray(steer.dcontrols, jnp.float32)  # coupled as SteerInputs says
        lat = (jnp.zeros((nb,), jnp.int32) if worlds is None
               else jnp.take(worlds.latency, world_of))

        def dtargets(t):
            if worlds is None:
                return dctrl[:, t]
            return delayed_at(dctrl, t, worlds).reshape(nb, nu)

        rates = None
        if steer.steering.track_turn:  # each ant's commanded rate, in each of its worlds
            if steer.rates is None:
                raise ValueError("steering.track_turn needs steer.rates, one per gait")
            rates = jnp.repeat(jnp.asarray(steer.rates, jnp.float32), r)

    mlim = mo.motor_model(spec) if limits else None
    mp0 = None if mp is None else ql.MotorParams(*(x[:, 0] for x in mp))

    def physics(dd):
        """One physics step; with the limits the command is this step's motor torque."""
        if limits:
            tau = ql.motor_torque(dd.qpos[:, qadr_all], dd.qvel[:, dofs], dd.ctrl, mp0, mlim)
            dn = dd.replace(ctrl=tau)
            dn = step(dn) if worlds is None else step(mmb, dn)
            return dn.replace(ctrl=dd.ctrl), tau
        return (step(dd) if worlds is None else step(mmb, dd)), None

    def control_step(carry, t):
        d, acc, alive, peak, sc = carry
        if steer is None:
            u = targets(t)
            u_next = targets(jnp.minimum(t + 1, n_steps - 1)) if interpolate else u
        else:
            state, u_prev_end = sc
            c_old = state.c_prev
            ref = None if rates is None else st.turn_reference(rates, t, spec.control_dt)
            state, c = st.update(state, root_trace(d.qpos), start_xy, steer.direction,
                                 steer.steering, spec.control_dt, ref=ref)
            c_eff = st.delayed(c, c_old, lat)[:, None]
            if interpolate:  # the command moves on from where the last step's ended
                u, tn = u_prev_end, jnp.minimum(t + 1, n_steps - 1)
                u_next = targets(tn) + c_eff * dtargets(tn)
            else:
                u = targets(t) + c_eff * dtargets(t)
                u_next = u
            sc = (state, u_next)
        # (nb, k, nu): this control step's physics steps' targets, held or interpolated
        us = mo.physics_targets(u, u_next, k, interpolate)
        d = d.replace(ctrl=u)
        if worlds is not None:
            qfrc = jnp.zeros((nb, model.nv), jnp.float32)
            qfrc = qfrc.at[:, :3].set(jnp.take(push_at(t, worlds), world_of, axis=0))
            d = d.replace(qfrc_applied=qfrc)
        if quality:
            def sub(dd, j):
                dd = dd.replace(ctrl=us[:, j])
                q, v0 = dd.qpos[:, qadr_all], dd.qvel[:, dofs]
                dd, tau = physics(dd)
                # with the limits: the speeds each torque was computed at (the step's start)
                return dd, (q, v0 if limits else dd.qvel[:, dofs], tau)

            d, (q, qdot, tau) = jax.lax.scan(sub, d, jnp.arange(k))
            keep = jnp.broadcast_to(alive[:, None], (nb, k))
            acc = ql.add_physics(acc, jnp.swapaxes(q, 0, 1), jnp.swapaxes(qdot, 0, 1),
                                 us, keep, mp, dt, el=el, step0=t,
                                 tau=None if tau is None else jnp.swapaxes(tau, 0, 1))
            soles = d.sensordata[:, sole_adr].reshape(nb, 1, -1, 3)
            acc = ql.add_control(acc, soles, alive[:, None], normal, radius)
        else:
            d = jax.lax.fori_loop(0, k, lambda j, dd: physics(dd.replace(ctrl=us[:, j]))[0], d)
        row = root_trace(d.qpos)
        alive = alive & ~is_down(row[:, :3], row[:, 3:6], spec.fall_height, spec.fall_tilt_deg,
                                 slope_deg)
        if warp:  # buffer use: contacts and broadphase pairs (all worlds), rows per world
            peak = jnp.maximum(peak, jnp.stack([warp_pairs(d), jnp.max(d._impl.nefc)]))
        return (d, acc, alive, peak, sc), (row, d.qpos if record else None)

    start = root_trace(data.qpos)
    start_xy = start[:, :2]
    sc0 = None if steer is None else (st.start_state(nb), targets(0))
    alive0 = ~is_down(start[:, :3], start[:, 3:6], spec.fall_height, spec.fall_tilt_deg, slope_deg)
    acc0 = (ql.new_acc((nb,), nu, motor=el is not None, trace_samples=ql.trace_samples(el))
            if quality else None)
    peak0 = jnp.zeros((2,), jnp.int32)
    (_, acc, _, peak, _), (trace, qpos) = jax.lax.scan(
        control_step, (data, acc0, alive0, peak0, sc0), jnp.arange(n_steps))
    if warp:
        jax.debug.callback(_warp_overflow, peak[0], peak[1], naconmax, njmax)
    out = {"trace": jnp.swapaxes(jnp.concatenate([start[None], trace], 0), 0, 1)}
    if record:
        out["qpos"] = jnp.swapaxes(jnp.concatenate([data.qpos[None], qpos], 0), 0, 1)
    if quality:
        out["acc"] = acc
    return out


def _torque_fields(fields: dict, dofs, keep: float) -> dict:
    """Per-world fields of the direct-torque model
    (:func:`~eaco_jax.gait.rollout_native.to_torque_actuators`): gain 1, no bias, the friction
    share ``keep`` of the actuated dofs' damping."""
    gain = jnp.zeros_like(fields["actuator_gainprm"]).at[..., 0].set(1.0)
    damping = fields["dof_damping"].at[..., np.asarray(dofs)].multiply(keep)
    return fields | {"actuator_gainprm": gain,
                     "actuator_biasprm": jnp.zeros_like(fields["actuator_biasprm"]),
                     "dof_damping": damping}


def mjx_trace(
    controls: jax.Array,
    spec: RobotSpec,
    slope_deg: float = 0.0,
    accuracy: str = "fast",
    record: bool = False,
):
    """Roll out control sequences ``controls`` ``(ants, T, nu)`` on MJX (nominal world).

    Returns the torso trace ``(ants, T + 1, 7)`` (and ``qpos`` ``(ants, T + 1, nq)`` when
    ``record``). Traceable: call it inside jit / scan.
    """
    out = mjx_rollout(controls, spec, slope_deg, accuracy, record=record)
    return (out["trace"], out["qpos"]) if record else out["trace"]
