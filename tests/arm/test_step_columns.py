"""The arm loop's block of step columns: what is written is what is read back, however it is sealed."""

from __future__ import annotations

import gc
import math
import weakref
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from isf_robot.arm.step_columns import StepColumns, TickValues

MJCF = """<mujoco><worldbody>
  <body name="a"><joint name="j0" type="hinge"/><joint name="j1" type="hinge" axis="1 0 0"/>
    <geom size="0.1"/><site name="ee" pos="0 0 0.2"/></body>
  <body name="ball" mocap="true"><geom size="0.05"/></body>
</worldbody></mujoco>"""

NC, NJ = 6, 4  # collision pairs, joint rows
NAMES = tuple(f"p{i}" for i in range(NC)) + tuple(f"j{i}" for i in range(NJ))


def _rows(rng: np.random.Generator, count: int) -> list[dict]:
    """Steps as the loop makes them: fresh arrays, a few near pairs (ascending), joint rows after them."""
    out = []
    for i in range(count):
        near = np.sort(rng.choice(NC, size=int(rng.integers(0, 4)), replace=False)).astype(np.int64)
        h = rng.normal(size=near.size + NJ)
        wit = rng.normal(size=(near.size, 3, 3))
        xi = rng.normal(size=int(rng.integers(0, 5)))
        step = SimpleNamespace(u=rng.normal(size=2), u_nom=rng.normal(size=2), on=bool(i % 3 == 0), xi=xi,
                               qp=object() if i % 2 else None, fallback=i == 7,
                               relaxed=("p1",) if i == 5 else (), event="switch" if i == 9 else None)
        out.append({"t": 0.002 * i, "step": step, "values": TickValues(near, h, wit), "goal": i % 2,
                    "q": rng.normal(size=2), "dist": float(rng.normal())})
    return out


def _block(capacity: int) -> tuple[StepColumns, mujoco.MjData, mujoco.MjModel]:
    model = mujoco.MjModel.from_xml_string(MJCF)
    data = mujoco.MjData(model)
    block = StepColumns(capacity, 2, NAMES, NC, model.nmocap, 0.002, h_far=np.full(NC, 0.5),
                        goals=np.array([[0.1, 0.0, 0.0], [0.2, 0.0, 0.0]]), nbody=model.nbody)
    block.bind(data, slice(0, 2), slice(0, 2), data.site_xpos[0])
    return block, data, model


def _layout(u: np.ndarray, layout: str) -> np.ndarray:
    """A command as a strategy might return it: float64 contiguous (the compiled copy), strided, or float32."""
    if layout == "strided":
        out = np.zeros(2 * u.size)
        out[::2] = u
        return out[::2]
    return u.astype(np.float32) if layout == "float32" else u


@pytest.mark.parametrize(("seal_every", "layout", "jit"), [(1, "float64", "1"), (7, "float64", "1"),
                                                           (10_000, "float64", "1"), (7, "strided", "1"),
                                                           (7, "float32", "1"), (7, "float64", "0"),
                                                           (7, "mixed", "1"), (10_000, "mixed", "1")])
def test_columns_hold_what_was_written(seal_every: int, layout: str, jit: str, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("ISF_ROBOT_JIT", jit)  # (the row's copy: compiled and called directly, else numpy's)
    rng = np.random.default_rng(seal_every)
    rows = _rows(rng, 300)
    for i, r in enumerate(rows):  # ("mixed": stretches of rows the compiled write takes and rows it leaves to NumPy)
        lay = ("float32" if i % 11 in (3, 4, 9) else "float64") if layout == "mixed" else layout
        r["step"].u, r["step"].u_nom = _layout(r["step"].u, lay), _layout(r["step"].u_nom, lay)
    block, data, model = _block(400)
    assert (block._copy is not None) == (jit == "1")  # (the compiled copy where it runs: the case under test)
    block.SEAL_ROWS = 64  # (an instance value: the loop's own seals between the explicit ones)
    want_pos, want_ee = [], []
    for i, r in enumerate(rows):
        data.qpos[:] = r["q"]
        data.mocap_pos[0] = [i, 0.0, 0.0]
        mujoco.mj_kinematics(model, data)
        want_pos.append(data.xpos.copy())
        want_ee.append(data.site_xpos[0].copy())
        block.write(r["t"], r["step"], r["values"], r["goal"])
        block.end_row(r["dist"])
        if (i + 1) % seal_every == 0:
            block.seal()
    block.seal()
    n = len(rows)
    assert len(block) == n
    np.testing.assert_array_equal(block.t[:n], [r["t"] for r in rows])
    np.testing.assert_array_equal(block.q[:n], [r["q"] for r in rows])
    np.testing.assert_array_equal(block.u[:n], [r["step"].u for r in rows])
    np.testing.assert_array_equal(block.goal_index[:n], [r["goal"] for r in rows])
    np.testing.assert_array_equal(block.fallback[:n], [r["step"].fallback for r in rows])
    np.testing.assert_array_equal(block.pair_start[1: n + 1], np.cumsum([len(r["values"].rows) for r in rows]))
    np.testing.assert_array_equal(block.u_nom[:n], [r["step"].u_nom for r in rows])
    np.testing.assert_array_equal(block.qd[:n], np.zeros((n, 2)))
    np.testing.assert_array_equal(block.ee_pos[:n], want_ee)
    np.testing.assert_array_equal(block.body_pos[:n], want_pos)
    np.testing.assert_array_equal(block.mocap_pos[:n, 0, 0], np.arange(n))
    np.testing.assert_array_equal(block.true_min[:n], [r["dist"] for r in rows])
    np.testing.assert_array_equal(block.on[:n], [r["step"].on for r in rows])
    np.testing.assert_array_equal(block.qp_solved[:n], [r["step"].qp is not None for r in rows])
    np.testing.assert_array_equal(block.xi_min[:n], [x.min() if x.size else math.inf
                                                     for x in (r["step"].xi for r in rows)])
    for i, r in enumerate(rows):
        near, h, wit = r["values"]
        full = np.full(NC + NJ, 0.5)
        full[near] = h[: near.size]
        full[NC:] = h[near.size:]
        np.testing.assert_array_equal(block.h[i], full)
        assert block.h_min[i] == full.min()
        a, b = block.pair_start[i], block.pair_start[i + 1]
        np.testing.assert_array_equal(block.pairs[a:b], near)
        np.testing.assert_array_equal(block.witness[a:b], wit[:, :2])
        rec = block.record(i)
        assert rec.witness_names == tuple(NAMES[k] for k in near)
        assert rec.relaxed == r["step"].relaxed and rec.event == r["step"].event
        np.testing.assert_array_equal(rec.goal_pos, [[0.1, 0, 0], [0.2, 0, 0]][r["goal"]])


@pytest.mark.parametrize("seed", [11, 12])
def test_read_only_and_strided_arrays_take_the_compiled_write_made_once_per_layout(seed: int, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Rows whose arrays are read-only (as a strategy may hand them back) or whose witness points are a strided
    view go the compiled way too, in blocks that first meet writable or read-only arrays alike: numba compiles the
    write once per layout of the witness points (it compiled it again for every mix of read-only arguments a block
    happened to meet first: five times in a test suite)."""
    monkeypatch.setenv("ISF_ROBOT_JIT", "1")
    rng = np.random.default_rng(seed)
    blocks = []
    for frozen in (False, True, "mixed"):  # (a block per kind of first row, each with both layouts)
        rows = _rows(rng, 40)
        for i, r in enumerate(rows):
            near, h, wit = r["values"]
            if i % 3 == 1:
                wit = wit[:, :2]  # (not contiguous)
            if frozen is True or (frozen == "mixed" and i % 2):
                for a in (near, h, wit, r["step"].xi):
                    a.setflags(write=False)
            r["values"] = TickValues(near, h, wit)
        block, data, model = _block(64)
        if block._copy is None:
            pytest.skip("the compiled write is not available")
        for r in rows:
            block.write(r["t"], r["step"], r["values"], r["goal"])
            assert block.sealed == len(block)  # (the compiled write takes the whole row at once; NumPy's, at a seal)
            block.end_row(r["dist"])
        blocks.append((block, rows))
    assert len(blocks[0][0]._copy[0].signatures) <= 2  # (contiguous witness points, strided ones; in every block)
    for block, rows in blocks:
        for i, r in enumerate(rows):
            near, h, wit = r["values"]
            a, b = block.pair_start[i], block.pair_start[i + 1]
            np.testing.assert_array_equal(block.pairs[a:b], near)
            np.testing.assert_array_equal(block.witness[a:b], wit[:, :2])
            np.testing.assert_array_equal(block.h[i, near], h[: near.size])
            assert block.xi_min[i] == (r["step"].xi.min() if r["step"].xi.size else math.inf)


@pytest.mark.parametrize("jit", ["1", "0"])
def test_the_loops_arrays_are_let_go_within_seal_rows(jit: str, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A kept view keeps the kernel's whole output block alive: the block lets each row's go at the next seal, and
    keeps none where the compiled write writes the whole row at once."""
    monkeypatch.setenv("ISF_ROBOT_JIT", jit)
    rows = _rows(np.random.default_rng(0), 40)
    block, _, _ = _block(100)
    block.SEAL_ROWS = 16
    refs = []
    for r in rows:
        refs.append(weakref.ref(r["values"].h))
        block.write(r["t"], r["step"], r["values"], r["goal"])
        block.end_row(r["dist"])
    del rows, r
    gc.collect()
    alive = [ref() is not None for ref in refs]
    if jit == "1":
        assert block._copy is not None and not block._rows and not any(alive)  # (nothing of a step kept)
    else:
        assert not any(alive[:32]) and all(alive[32:])  # (two seals of 16 rows; the last 8 wait for the next)


def test_write_checks() -> None:
    block, _, _ = _block(1)
    fresh = StepColumns(1, 2, NAMES, NC, 0, 0.002)
    r = _rows(np.random.default_rng(1), 2)
    with pytest.raises(RuntimeError, match="bind"):
        fresh.write(0.0, r[0]["step"], r[0]["values"], 0)
    block.write(0.0, r[0]["step"], r[0]["values"], 0)
    with pytest.raises(IndexError, match="full"):
        block.write(0.002, r[1]["step"], r[1]["values"], 0)
    block.clear()
    assert len(block) == 0 and block.true_min[0] == math.inf
    bad = SimpleNamespace(**{**vars(r[0]["step"]), "u": np.arange(3.0), "u_nom": np.arange(1.0)})
    before = (block._row_state.copy(), block.h.copy(), block.t.copy())
    with pytest.raises(ValueError, match="commands of 3 and 1 joints"):  # (the total width matches; the split not)
        block.write(0.0, bad, r[0]["values"], 0)
    # (the compiled write refuses such a row before it writes anything; the NumPy way then says what is wrong)
    assert len(block) == 0 and all(np.array_equal(a, b) for a, b in
                                   zip(before, (block._row_state, block.h, block.t)))


@pytest.mark.parametrize("witness_of", ["one", "none"])
def test_a_row_whose_witness_points_do_not_match_its_pairs_is_an_error(witness_of: str) -> None:
    block, _, _ = _block(4)
    near = np.array([1, 3], dtype=np.int64)
    rows = _rows(np.random.default_rng(3), 2)
    for i, r in enumerate(rows):
        wit = np.zeros((1, 3, 3)) if i == 0 else (None if witness_of == "none" else np.zeros((2, 3, 3)))
        block.write(r["t"], r["step"], TickValues(near, np.zeros(near.size + NJ), wit), 0)
        block.end_row(0.1)
    with pytest.raises(ValueError, match=r"witness points of [13] pairs for [24] near pairs"):
        block.seal()


def test_team_columns_keep_each_arms_mode_end_effector_and_goal() -> None:
    from isf_robot.arm.team_columns import TeamStepColumns

    model = mujoco.MjModel.from_xml_string(MJCF.replace('<site name="ee" pos="0 0 0.2"/>',
                                                        '<site name="ee" pos="0 0 0.2"/><site name="ee2" pos="0.1 0 0"/>'))
    data = mujoco.MjData(model)
    block = TeamStepColumns(10, 2, NAMES, NC, model.nmocap, 0.002, ("left", "right"), nbody=model.nbody)
    block.bind(data, slice(0, 2), slice(0, 2), data.site_xpos[0])
    goals = [np.array([[1.0, 0, 0], [2.0, 0, 0]]), np.array([[0, 3.0, 0]])]
    block.bind_arms(data.site_xpos, [1, 0], goals)
    rows = _rows(np.random.default_rng(2), 4)
    want_ee = []
    for i, r in enumerate(rows):
        data.qpos[:] = r["q"]
        mujoco.mj_kinematics(model, data)
        want_ee.append(data.site_xpos[[1, 0]].copy())
        block.write(r["t"], r["step"], r["values"], r["goal"])
        block.write_arms([(i % 2 == 0, False), (True, i == 3)], [i % 2, 0 if i < 2 else -1])
    np.testing.assert_array_equal(block.arm_ee[:4], want_ee)
    np.testing.assert_array_equal(block.arm_on[:4], [[True, True], [False, True]] * 2)
    np.testing.assert_array_equal(block.arm_qp[:4, 1], [False, False, False, True])
    goal = block.arm_goal
    np.testing.assert_array_equal(goal[:, 0, 0], [1.0, 2.0, 1.0, 2.0])
    np.testing.assert_array_equal(goal[:2, 1], [[0, 3.0, 0]] * 2)
    assert np.isnan(goal[2:, 1]).all()
    with pytest.raises(ValueError, match="one end-effector site"):
        block.bind_arms(data.site_xpos, [0], goals)

    block.clear()  # (an arm without an end-effector site: NaN, not the model's last site)
    block.bind_arms(data.site_xpos, [-1, 0], goals)
    for r in rows[:2]:
        block.write(r["t"], r["step"], r["values"], r["goal"])
        block.write_arms([(False, False), (True, True)], [0, 0])
    assert np.isnan(block.arm_ee[:2, 0]).all()
    np.testing.assert_array_equal(block.arm_ee[:2, 1], [data.site_xpos[0]] * 2)


def test_flat_buffers_grow_rows_without_witness_points_and_blocks_reused() -> None:
    rng = np.random.default_rng(3)
    block, data, model = _block(60)
    block.SEAL_ROWS = 7
    block._pairs, block._witness = block._pairs[:5], block._witness[:5]  # (room for 5 pairs: the buffers must grow)
    for _ in range(3):  # (three blocks through clear())
        rows = _rows(rng, 50)
        for i, r in enumerate(rows):
            near, h, wit = r["values"]
            values = TickValues(near, h, None) if i % 4 == 0 else r["values"]
            block.write(r["t"], r["step"], values, r["goal"])
            block.end_row(r["dist"])
        block.seal()
        for i, r in enumerate(rows):
            near, h, wit = r["values"]
            a, b = block.pair_start[i], block.pair_start[i + 1]
            np.testing.assert_array_equal(block.pairs[a:b], near)
            if i % 4 == 0:
                assert np.isnan(block.witness[a:b]).all()
            else:
                np.testing.assert_array_equal(block.witness[a:b], wit[:, :2])
            assert block.events.get(i) == r["step"].event
        block.clear()
    with pytest.raises(IndexError, match="no row"):
        block.end_row(0.0)


@pytest.mark.parametrize("fail_in", ["on_steps", "finish"])
def test_a_failure_after_the_last_step_aborts_the_observers_once(monkeypatch, fail_in: str) -> None:
    """The run's last block and its summary are inside the run's error handling: observers get ``on_abort``."""
    from isf_robot.arm import sim as arm_sim
    from isf_robot.arm.params import resolve_params
    from isf_robot.arm.scene import load_scene

    calls: list[str] = []

    class Blocks:
        def on_start(self, info): calls.append("start")  # type: ignore[no-untyped-def]
        def on_event(self, ev): ...  # type: ignore[no-untyped-def]
        def on_finish(self, summary): calls.append("finish")  # type: ignore[no-untyped-def]
        def on_abort(self, exc): calls.append(f"abort:{exc}")  # type: ignore[no-untyped-def]

        def on_steps(self, block):  # type: ignore[no-untyped-def]
            calls.append(f"steps:{len(block)}")
            if fail_in == "on_steps":
                raise RuntimeError("disk full")

    if fail_in == "finish":
        def finish(self, wall, timings):  # type: ignore[no-untyped-def]
            raise RuntimeError("disk full")
        monkeypatch.setattr(arm_sim._Episode, "finish", finish)
    scene = load_scene("panda_pole")
    sim = arm_sim.ArmSimulation(scene, "nominal", seed=0, params=resolve_params(scene), observers=[Blocks()])
    with pytest.raises(RuntimeError, match="disk full"):
        sim.run(0.05)  # (fewer steps than a block: all of them go on after the loop)
    steps = int(round(0.05 / sim.control_period))
    assert calls == ["start", f"steps:{steps}", "abort:disk full"]  # (the block handed on once, then the abort)


@pytest.mark.parametrize("width", ["3", "2", "2view", "mixed"])
def test_witness_points_of_either_width_read_back(width: str) -> None:
    """The tick's witness points as the kernel hands them (pair, 3, 3), as the numpy paths do ((pair, 2, 3), a copy
    or a view), or both in one stretch of rows: the first two points of each pair are what is read back."""
    rng = np.random.default_rng(11)
    rows = _rows(rng, 200)
    for i, r in enumerate(rows):
        near, h, wit = r["values"]
        if width == "2" or (width == "mixed" and i % 5 == 2):
            wit = wit[:, :2].copy()
        elif width == "2view":
            wit = wit[:, :2]
        r["values"] = TickValues(near, h, wit)
    block, data, model = _block(256)
    block.SEAL_ROWS = 64
    for r in rows:
        block.write(r["t"], r["step"], r["values"], r["goal"])
        block.end_row(r["dist"])
    block.seal()
    assert block.witness.shape == (int(block.pair_start[len(rows)]), 2, 3)
    for i, r in enumerate(rows):
        near, _, wit = r["values"]
        a, b = block.pair_start[i], block.pair_start[i + 1]
        np.testing.assert_array_equal(block.witness[a:b], wit[:, :2])
        np.testing.assert_array_equal(block.record(i).witness, wit[:, :2])


@pytest.mark.parametrize("strategy", ["isf", "nominal"])
def test_the_arm_loop_takes_the_compiled_write_at_every_step(strategy: str, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """With numba, every row of an arm run goes the compiled way (its direct call: the loop's arrays have the types it
    was made for), so nothing of a step waits for a seal; the kernel path's witness points (isf) and the filter
    rows' strided ones (nominal) alike."""
    from isf_robot.arm import sim as arm_sim
    from isf_robot.arm.params import resolve_params
    from isf_robot.arm.scene import load_scene
    from isf_robot.core import Observer

    monkeypatch.setenv("ISF_ROBOT_JIT", "1")
    taken: list[bool] = []
    write = StepColumns._write_compiled

    def counted(self, *args):  # type: ignore[no-untyped-def]
        taken.append(write(self, *args))
        return taken[-1]

    monkeypatch.setattr(StepColumns, "_write_compiled", counted)
    sizes: list[int] = []

    class Blocks(Observer):
        block_steps = 64

        def on_steps(self, block):  # type: ignore[no-untyped-def]
            assert block._copy is not None and not block._rows and block.sealed == len(block)
            sizes.append(len(block))

    scene = load_scene("panda_pole")
    res = arm_sim.ArmSimulation(scene, strategy, seed=0, params=resolve_params(scene), observers=[Blocks()]).run(0.3)
    assert sum(sizes) == res.control_steps == len(taken) and all(taken)


def test_a_copy_writes_its_own_arrays_not_the_originals(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    import copy

    monkeypatch.setenv("ISF_ROBOT_JIT", "1")
    rows = _rows(np.random.default_rng(5), 3)
    block, data, model = _block(8)
    if block._copy is None:
        pytest.skip("the compiled write is not available")
    twin = copy.deepcopy(block)
    assert twin._copy is None  # (its table would hold the original's addresses: the copy writes the NumPy way)
    for r in rows:
        data.qpos[:] = r["q"]
        mujoco.mj_kinematics(model, data)
        twin.write(r["t"], r["step"], r["values"], r["goal"])
        twin.end_row(r["dist"])
    twin.seal()
    assert len(block) == 0 and not block.t[:3].any()  # (nothing reached the original's arrays)
    np.testing.assert_array_equal(twin.t[:3], [r["t"] for r in rows])


def test_least_is_numpys_minimum_with_nan_and_empty() -> None:
    pytest.importorskip("numba")  # (the module of the compiled write imports it)
    from isf_robot.arm._columns_jit import least

    rng = np.random.default_rng(3)
    for a in (rng.normal(size=7), np.array([2.0, np.nan, -5.0]), np.array([np.inf, 1.0])):
        want = np.min(a)
        assert least(a) == want or (np.isnan(want) and np.isnan(least(a)))
    assert least(np.zeros(0)) == np.inf  # (a row of no values: no minimum, as the NumPy way writes it)
