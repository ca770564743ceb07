"""The collision kernel's output blocks (:class:`~isf_robot.arm.output_blocks.BlockPool`): an allocation is reused
only when nothing holds a view of it; a reused block gives the same rows as a fresh one; kept results are never
written again."""

from __future__ import annotations

import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, JointLimitBarriers, kernels, load_scene, output_blocks
from isf_robot.arm.output_blocks import BlockPool

needs_kernel = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")


def _barriers(scene) -> CollisionBarriers:  # type: ignore[no-untyped-def]
    return CollisionBarriers.from_scene(scene)  # (the arms' pairs too)


def _equal(xs: list[np.ndarray], ys: list[np.ndarray]) -> bool:
    return all(x.shape == y.shape and np.array_equal(x, y) for x, y in zip(xs, ys))


def test_reference_counts_tell_views_here() -> None:
    assert output_blocks.REUSE  # (CPython: else the pools allocate every time, as fresh as ever)


def test_without_reuse_every_allocation_is_new(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setattr(output_blocks, "REUSE", False)
    pool = BlockPool(8, 1, 1, 1, 1)
    for _ in range(3):
        pool.take()
    assert pool.made == 3


def test_a_block_is_reused_only_when_nothing_holds_it() -> None:
    pool = BlockPool(40, 4, 3, 5, 2)
    blk, rows, g = pool.take()
    assert blk.shape == (40,) and rows.shape == (5,) and rows.dtype == np.int64 and g.shape == (4, 3)
    g[:] = 1.0
    assert (blk[4:16] == 1.0).all()  # (g: the block's gradient rows, from float m on)
    first = {id(blk.base), id(rows.base)}
    blk2, _, _ = pool.take()  # (the allocation's second block)
    assert blk2.base is blk.base and not np.shares_memory(blk, blk2)
    kept = blk[:3]
    del blk, rows, g, blk2
    b3 = pool.take()  # (a view is kept: another allocation)
    assert id(b3[0].base) not in first and pool.made == 2
    del b3
    pool.take()
    pool.take()  # (the second allocation is free again: reused, while the first stays held)
    assert pool.made == 2
    del kept
    for _ in range(6):  # (nothing held: no new allocation)
        pool.take()
    assert pool.made == 2


def test_a_whole_allocation_is_reused_only_when_nothing_holds_it() -> None:
    pool = BlockPool(40, 4, 3, 5, 10)
    blk, g, rows = pool.take_all()
    assert blk.shape == (10, 40) and g.shape == (10, 4, 3) and rows.shape == (10, 5)
    ids = id(blk)
    del blk, g, rows
    blk, g, rows = pool.take_all()
    assert id(blk) == ids and pool.made == 1
    held = g[3]
    del blk, g, rows
    blk, g, rows = pool.take_all()
    assert pool.made == 2 and not np.shares_memory(blk, held)


@pytest.mark.skipif(not output_blocks.REUSE, reason="allocations are not reused here")
def test_an_allocation_whose_gradient_array_alone_is_kept_is_not_reused() -> None:
    """``take_all``'s gradient array is handed out as the pool holds it (a rollout's points keep it as their
    ``lg``): kept alone, without the float block and the rows, it keeps its allocation out of use."""
    pool = BlockPool(40, 4, 3, 5, 10)
    blk, g, rows = pool.take_all()
    g[:] = 1.0
    kept = g
    del blk, g, rows
    blk, g, rows = pool.take_all()
    blk[:] = 2.0
    assert pool.made == 2 and not np.shares_memory(blk, kept) and (kept == 1.0).all()


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copied_pool_hands_out_blocks_whose_gradient_is_the_block(how: str) -> None:
    """A copy of a pool that holds allocations: its blocks' gradient views are views of its blocks (a copy of an
    allocation would make the view a separate array, and the kernel's writes to the block would not reach it)."""
    import copy
    import pickle

    pool = BlockPool(40, 4, 3, 5, 2)
    blk0, _, g0 = pool.take()
    g0[:] = 7.0
    twin = copy.deepcopy(pool) if how == "deepcopy" else pickle.loads(pickle.dumps(pool))
    for _ in range(3):  # (past the end of the current allocation, and into a reuse)
        blk, rows, g = twin.take()
        blk[:] = 0.0
        blk[4:16] = np.arange(12.0)
        assert np.array_equal(g.ravel(), np.arange(12.0)) and np.shares_memory(blk, g)
        del blk, rows, g
    fb, fg, _ = twin.take_all()
    fb[:, 4:16] = 3.0
    assert (fg == 3.0).all() and (g0 == 7.0).all() and (blk0[4:16] == 7.0).all()  # (the original untouched)


def test_the_pool_keeps_a_bounded_number_of_allocations() -> None:
    pool = BlockPool(8, 1, 1, 1, 1)
    kept = [pool.take() for _ in range(3 * BlockPool.KEEP)]  # (every one held: a new allocation each time)
    assert pool.made == 3 * BlockPool.KEEP and len(pool._allocs) == BlockPool.KEEP
    assert len({id(b.base) for b, _, _ in kept}) == len(kept)


@needs_kernel
@pytest.mark.parametrize("name", ["panda_pair", "panda_quad"])
def test_reused_blocks_give_the_rows_of_fresh_ones_and_kept_rows_stay(name, random_states, rng) -> None:  # type: ignore[no-untyped-def]
    """Rows dropped after each call (blocks reused) equal a fresh barrier object's; rows kept are never rewritten."""
    scene = load_scene(name)
    reused, fresh = _barriers(scene), _barriers(scene)
    joints = JointLimitBarriers.from_scene(scene)
    kept, made = [], 0
    for i, d in enumerate(random_states(scene, rng, 30)):
        t = reused.lie_rows(d, joints)
        f = _barriers(scene).lie_rows(d, joints) if i % 3 == 0 else fresh.lie_rows(d, joints)
        got = [t.lie.h, t.lie.lf, t.lie.lg, t.lie.grad_norm, t.rows]
        assert _equal(got, [f.lie.h, f.lie.lf, f.lie.lg, f.lie.grad_norm, f.rows])
        assert t.lie.names == f.lie.names and t.row_list == f.row_list
        if i >= 15 and i % 2:  # (the second half: some kept past later calls)
            kept.append((got, [a.copy() for a in got]))
        del t, f, got
        if i == 14:
            made = reused._kout[1].made
    assert made == 1  # (nothing kept: one allocation's blocks serve every call)
    assert reused._kout[1].made > 1
    assert all(_equal(got, copies) for got, copies in kept)
