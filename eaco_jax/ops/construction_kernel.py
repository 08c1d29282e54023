"""Tour construction as ONE Pallas kernel: each program builds the whole tours of a block of ants.

The scan plans of :mod:`eaco_jax.ops.construction` run one batched step per tour position:
on a GPU each step is a dozen small kernels, each with its launch and sync latency, which caps
their tours per second however large the colony (claim ``tsp-gpu-scan-pr1002-65536``; this
kernel: ``tsp-gpu-kernel-pr1002-16384``). Here a program owns ``block`` ants and loops over
all tour positions itself, keeping each ant's current node in registers; per step and ant it
reads the k candidates of its row and their choice info (one table, cached), one tabu word per
candidate (the tabu set is a bit mask in global memory, an ant's 128 bytes for n = 1,002), its
uniform, and writes one path entry and one tabu word. Nothing waits on the host.

The rule is that of every other plan (see ``construct_tours``): Eq. 2 and the q0 rule on the
candidates that are not tabu, else the first allowed node of the row's backup list, else the
allowed node of largest weight in the whole row (ACOTSP's rule), the first allowed node when
all those weights are 0; the uniforms are the same draws. The fallbacks serve one pending ant
at a time, its backup list or row spread over the program's threads, so they cost in
proportion to the ants that need them (vectorised over the block they were an order of
magnitude slower: claim ``tsp-gpu-kernel-serial-over-tile``). The candidates' prefix sums are
added one candidate after another here (the scan plans use a small matmul), so a sampled node
could differ where a draw falls within a rounding step of a boundary; the tests find the
tours of every other plan (on a CPU, and for 4,096 pr1002 tours on a GPU). Greedy choices, the
backup lists and the whole-row rule are exact integer maxima and agree always.

Runs as a Triton kernel on a GPU; elsewhere in Pallas' interpreter (slow: for tests).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from jax.experimental import pallas as pl

from eaco_jax.ops.packed_keys import bit_allowed, id_bits, packed_keys

Array = jax.Array

#: ants per program (a power of 2 >= 16; one warp per 32 ants, one ant per thread), and the
#: claim whose benchmark chose it (while a program serves one ant's fallback, the other ants of
#: its block wait: fewer of them in a small block)
BLOCK = 32
BLOCK_CLAIM = "tsp-gpu-kernel-block32-over-128"


def _any(x: Array) -> Array:
    """Whether any entry is True (a max: Triton has no boolean reduction)."""
    return jnp.max(x.astype(jnp.int32)) > 0


def _ant_blocks(m: int, block: int) -> tuple[int, int]:
    """The block actually used for ``m`` ants (a power of 2, at least 16, at most the next
    power of 2 of ``m``) and the padded number of ants, a multiple of it."""
    block = max(16, min(block, 1 << max(0, (m - 1).bit_length())))
    return block, -(-m // block) * block


def _triton_params(block: int, interpret: bool) -> dict:
    """``pallas_call``'s compiler parameters on a GPU: one warp per 32 ants of a block."""
    if interpret:
        return {}
    from jax.experimental.pallas import triton as pltriton

    return {"compiler_params": pltriton.CompilerParams(num_warps=max(1, block // 32),
                                                       num_stages=1)}


def _candidate_choice(row: Array, u: Array, q0: Array, ants: Array, word_base: Array, *,
                      cand_ref, cw_ref, bits_ref, factor_ref, n: int, k: int,
                      block: int) -> tuple[Array, Array]:
    """Eq. 2 and the q0 rule on row ``row``'s k candidates for each ant of the block: whether
    any candidate is allowed (``ok``) and the chosen node (meaningful where ``ok``). The
    candidates' weights, greedy key and prefix sums are taken one column at a time."""
    cand_bits = id_bits(k)
    nodes, weights, cums = [], [], []
    best_key = jnp.zeros((block,), jnp.int32)
    total = jnp.zeros((block,), jnp.float32)
    for j in range(k):
        node = cand_ref[row * k + j]
        w = jnp.where(bit_allowed(bits_ref, word_base, node), cw_ref[row * k + j], 0.0)
        if factor_ref is not None:
            w = w * factor_ref[ants * n + node]
        best_key = jnp.maximum(best_key, packed_keys(w, jnp.int32(j), cand_bits))
        total = total + w
        nodes.append(node)
        weights.append(w)
        cums.append(total)
    ok = (best_key >> cand_bits) > 0
    greedy = best_key & ((1 << cand_bits) - 1)
    v = (u - q0) / jnp.maximum(1.0 - q0, 1e-12)
    target = jnp.maximum(v * total, jnp.finfo(jnp.float32).tiny)
    sampled = jnp.zeros((block,), jnp.int32)
    for c in cums:
        sampled = sampled + (c < target).astype(jnp.int32)
    sampled = jnp.minimum(sampled, k - 1)
    hit = jnp.zeros((block,), jnp.float32)
    for j in range(k):
        hit = jnp.where(sampled == j, weights[j], hit)
    choice = jnp.where((u < q0) | ~(hit > 0), greedy, sampled)
    nxt = jnp.zeros((block,), jnp.int32)
    for j in range(k):
        nxt = jnp.where(choice == j, nodes[j], nxt)
    return ok, nxt


def _visit(nxt: Array, pos: Array, ants: Array, word_base: Array, *, bits_ref, path_ref,
           m_pad: int) -> None:
    """Mark ``nxt`` tabu in each ant's bit mask and write it at tour position ``pos``."""
    word = bits_ref[word_base + (nxt >> 5)]
    bits_ref[word_base + (nxt >> 5)] = word & ~(jnp.uint32(1) << (nxt & 31).astype(jnp.uint32))
    path_ref[pos * m_pad + ants] = nxt


def _kernel(*refs, n: int, k: int, words: int, backup: int, has_factor: bool, block: int,
            m_pad: int):
    it = iter(refs)
    start_ref, offset_ref, q0_ref, u_ref, cand_ref, cw_ref, w_ref = (next(it) for _ in range(7))
    bk_node_ref = bk_ok_ref = factor_ref = None
    if backup:
        bk_node_ref, bk_ok_ref = next(it), next(it)
    if has_factor:
        factor_ref = next(it)
    bits_in_ref = next(it)  # aliased with bits_ref
    del bits_in_ref
    path_ref, bits_ref = next(it), next(it)

    first_ant = pl.program_id(0) * block
    ants = first_ant + jnp.arange(block, dtype=jnp.int32)
    word_base = ants * words
    offset = offset_ref[ants]
    q0 = q0_ref[ants]
    row_bits = id_bits(n)
    start = start_ref[ants]
    path_ref[ants] = start  # position 0 of the (n, m_pad) path

    lane = jnp.arange(block, dtype=jnp.int32)
    row_width = 1 << max(0, (n - 1).bit_length())

    def pick(vec: Array, a: Array) -> Array:
        """Entry ``a`` of a per-lane vector, as a scalar."""
        return jnp.sum(jnp.where(lane == a, vec, 0))

    def whole_row(current: Array, left: Array, nxt: Array) -> Array:
        """The whole-row rule for ants ``left``, one at a time, its row spread over the block's
        threads: the cost follows the number of such ants, not block x n."""
        cols = jnp.arange(row_width, dtype=jnp.int32)
        node = jnp.minimum(cols, n - 1)

        def body(carry):
            nxt, left = carry
            a = jnp.min(jnp.where(left, lane, block))
            ant = first_ant + a
            alive = bit_allowed(bits_ref, ant * words, node) & (cols < n)
            w = jnp.where(alive, w_ref[(pick(offset, a) + pick(current, a)) * n + node], 0.0)
            if has_factor:
                w = w * factor_ref[ant * n + node]
            best_key = jnp.max(jnp.where(alive, packed_keys(w, node, row_bits), 0))
            first = jnp.min(jnp.where(alive, node, n))
            best = jnp.where((best_key >> row_bits) > 0, best_key & ((1 << row_bits) - 1),
                             jnp.minimum(first, n - 1))
            return jnp.where(lane == a, best, nxt), left & (lane != a)

        return jax.lax.while_loop(lambda c: _any(c[1]), body, (nxt, left))[0]

    def backup_list(row: Array, nxt: Array, pending: Array):
        """The first allowed node of the backup list for ants ``pending``, one at a time (the
        list spread over the block's threads); ants whose list is all tabu stay pending."""
        j = jnp.arange(backup, dtype=jnp.int32)

        def body(carry):
            nxt, pending, todo = carry
            a = jnp.min(jnp.where(todo, lane, block))
            ant = first_ant + a
            idx = pick(row, a) * backup + j
            bk = bk_node_ref[idx]
            valid = (bk_ok_ref[idx] != 0) & bit_allowed(bits_ref, ant * words, bk)
            first = jnp.min(jnp.where(valid, j, backup))
            best = jnp.sum(jnp.where(j == first, bk, 0))
            here = lane == a
            found = first < backup
            return (jnp.where(here & found, best, nxt), pending & ~(here & found),
                    todo & ~here)

        out = jax.lax.while_loop(lambda c: _any(c[2]), body, (nxt, pending, pending))
        return out[0], out[1]

    def step(pos, current):
        row = offset + current
        u = u_ref[(pos - 1) * m_pad + ants]
        ok, nxt = _candidate_choice(row, u, q0, ants, word_base, cand_ref=cand_ref,
                                    cw_ref=cw_ref, bits_ref=bits_ref, factor_ref=factor_ref,
                                    n=n, k=k, block=block)
        pending = ~ok
        if backup:
            nxt, pending = backup_list(row, nxt, pending)
        nxt = whole_row(current, pending, nxt)
        _visit(nxt, pos, ants, word_base, bits_ref=bits_ref, path_ref=path_ref, m_pad=m_pad)
        return nxt

    jax.lax.fori_loop(1, n, step, start)


@functools.partial(jax.jit, static_argnames=("backup", "block", "interpret"))
def construct_tours_kernel(uniforms: Array, weights: Array, starts: Array, q0: Array,
                           row_offset: Array, factor: Array | None, candidates: Array,
                           cand_w: Array, bk_node: Array | None, bk_ok: Array | None,
                           alive_bits: Array, *, backup: int, interpret: bool,
                           block: int = BLOCK) -> Array:
    """(m, n) tours from the tables of ``construction._candidate_tables``.

    ``uniforms`` (n - 1, m): the draw of each tour position and ant; ``cand_w`` (R, k) the
    choice info of the candidates (R = rows of ``weights``); ``bk_node``/``bk_ok`` (R, backup)
    the backup lists or None; ``alive_bits`` (m, words) uint32 the initial tabu bit masks.
    """
    n = weights.shape[1]
    m = starts.shape[0]
    k = candidates.shape[1]
    words = alive_bits.shape[1]
    block, m_pad = _ant_blocks(m, block)
    pad = m_pad - m
    if max(n * m_pad, weights.shape[0] * n) >= 2**31:  # the kernel's flat int32 indices
        raise ValueError(f"plan 'kernel' indexes ants x cities with int32: {m} ants x {n} "
                         "cities is too many; use fewer ants or another construction plan")

    def padded(x, value):
        return jnp.pad(x, [(0, pad)] + [(0, 0)] * (x.ndim - 1), constant_values=value)

    starts = padded(starts.astype(jnp.int32), 0)
    bits = padded(alive_bits, jnp.uint32(0xFFFFFFFF))
    u = jnp.pad(uniforms, ((0, 0), (0, pad)), constant_values=0.5).reshape(-1)
    args = [starts, padded(row_offset.astype(jnp.int32), 0), padded(q0, 0.0), u,
            candidates.astype(jnp.int32).reshape(-1), cand_w.reshape(-1), weights.reshape(-1)]
    if backup:
        args += [bk_node.astype(jnp.int32).reshape(-1), bk_ok.astype(jnp.int32).reshape(-1)]
    has_factor = factor is not None
    if has_factor:
        args.append(padded(factor, 1.0).reshape(-1))
    args.append(bits.reshape(-1))
    kernel = functools.partial(_kernel, n=n, k=k, words=words, backup=backup,
                               has_factor=has_factor, block=block, m_pad=m_pad)
    path, _ = pl.pallas_call(
        kernel,
        out_shape=(jax.ShapeDtypeStruct((n * m_pad,), jnp.int32),
                   jax.ShapeDtypeStruct((m_pad * words,), jnp.uint32)),
        grid=(m_pad // block,),
        input_output_aliases={len(args) - 1: 1},
        interpret=interpret,
        **_triton_params(block, interpret),
    )(*args)
    return path.reshape(n, m_pad)[:, :m].T


def _sparse_kernel(*refs, n: int, k: int, words: int, has_factor: bool, block: int,
                   m_pad: int, cap: int | None):
    """The kernel of :func:`construct_tours_sparse_kernel`: :func:`_kernel`'s candidate step,
    and where every candidate is tabu (or an ant has added ``cap`` new edges) the next city of
    the ant's linked list in reference-tour order, for all pending ants at once (no serial
    fallback: the list answers in O(1))."""
    it = iter(refs)
    start_ref, offset_ref, q0_ref, u_ref, cand_ref, cw_ref = (next(it) for _ in range(6))
    succ_ref = pred_ref = factor_ref = None
    if cap is not None:
        succ_ref, pred_ref = next(it), next(it)
    if has_factor:
        factor_ref = next(it)
    for _ in range(3):  # the aliased inputs of the outputs below
        next(it)
    path_ref, bits_ref, nxt_ref, prv_ref = (next(it) for _ in range(4))

    first_ant = pl.program_id(0) * block
    ants = first_ant + jnp.arange(block, dtype=jnp.int32)
    word_base = ants * words
    list_base = ants * n
    offset = offset_ref[ants]
    q0 = q0_ref[ants]
    start = start_ref[ants]
    path_ref[ants] = start

    def step(pos, carry):
        current, new = carry
        row = offset + current
        u = u_ref[(pos - 1) * m_pad + ants]
        ok, nxt = _candidate_choice(row, u, q0, ants, word_base, cand_ref=cand_ref,
                                    cw_ref=cw_ref, bits_ref=bits_ref, factor_ref=factor_ref,
                                    n=n, k=k, block=block)
        if cap is not None:
            ok = ok & (new < cap)
        nxt = jnp.where(ok, nxt, nxt_ref[list_base + current])
        if cap is not None:
            fresh = (nxt != succ_ref[current]) & (nxt != pred_ref[current])
            new = new + fresh.astype(jnp.int32)
        p = prv_ref[list_base + nxt]
        s = nxt_ref[list_base + nxt]
        nxt_ref[list_base + p] = s
        prv_ref[list_base + s] = p
        _visit(nxt, pos, ants, word_base, bits_ref=bits_ref, path_ref=path_ref, m_pad=m_pad)
        return nxt, new

    jax.lax.fori_loop(1, n, step, (start, jnp.zeros((block,), jnp.int32)))


@functools.partial(jax.jit, static_argnames=("cap", "block", "interpret"))
def construct_tours_sparse_kernel(uniforms: Array, cand_w: Array, candidates: Array,
                                  starts: Array, q0: Array, row_offset: Array,
                                  factor: Array | None, alive_bits: Array, nxt_l: Array,
                                  prv_l: Array, succ: Array, pred: Array, *, cap: int | None,
                                  interpret: bool, block: int = BLOCK) -> Array:
    """(m, n) tours of ``construction_sparse.construct_tours_sparse`` as one kernel.

    ``cand_w`` (R, k) choice information, ``candidates`` (n, k); ``alive_bits`` (m, words)
    the initial tabu bit masks, ``nxt_l``/``prv_l`` (m, n) each ant's linked list of the
    cities left in reference order (the start already unlinked), ``succ``/``pred`` (n,) the
    reference tour's neighbours (read only with ``cap``, the focused construction's limit).
    """
    n, k = candidates.shape
    m = starts.shape[0]
    rows = cand_w.shape[0]
    words = alive_bits.shape[1]
    block, m_pad = _ant_blocks(m, block)
    pad = m_pad - m
    if max(n * m_pad, rows * k) >= 2**31:
        raise ValueError(f"plan 'kernel' indexes ants x cities with int32: {m} ants x {n} "
                         "cities is too many; use fewer ants")

    def padded(x, value):
        return jnp.pad(x, [(0, pad)] + [(0, 0)] * (x.ndim - 1), constant_values=value)

    def padded_lists(x):  # padded ants build a throw-away tour over the reference order
        return jnp.concatenate([x, jnp.broadcast_to(x[:1], (pad, n))], axis=0) if pad else x

    cands = jnp.concatenate([candidates.astype(jnp.int32)] * (rows // n), axis=0)
    u = jnp.pad(uniforms, ((0, 0), (0, pad)), constant_values=0.5).reshape(-1)
    args = [padded(starts.astype(jnp.int32), 0), padded(row_offset.astype(jnp.int32), 0),
            padded(q0, 0.0), u, cands.reshape(-1), cand_w.reshape(-1)]
    if cap is not None:
        args += [succ.astype(jnp.int32), pred.astype(jnp.int32)]
    has_factor = factor is not None
    if has_factor:
        args.append(padded(factor, 1.0).reshape(-1))
    first_alias = len(args)
    args += [padded(alive_bits, jnp.uint32(0xFFFFFFFF)).reshape(-1),
             padded_lists(nxt_l.astype(jnp.int32)).reshape(-1),
             padded_lists(prv_l.astype(jnp.int32)).reshape(-1)]
    kernel = functools.partial(_sparse_kernel, n=n, k=k, words=words, has_factor=has_factor,
                               block=block, m_pad=m_pad, cap=cap)
    path, _, _, _ = pl.pallas_call(
        kernel,
        out_shape=(jax.ShapeDtypeStruct((n * m_pad,), jnp.int32),
                   jax.ShapeDtypeStruct((m_pad * words,), jnp.uint32),
                   jax.ShapeDtypeStruct((m_pad * n,), jnp.int32),
                   jax.ShapeDtypeStruct((m_pad * n,), jnp.int32)),
        grid=(m_pad // block,),
        input_output_aliases={first_alias: 1, first_alias + 1: 2, first_alias + 2: 3},
        interpret=interpret,
        **_triton_params(block, interpret),
    )(*args)
    return path.reshape(n, m_pad)[:, :m].T
