"""``gather_rows``: each agent's rows ``lg[rows][:, cols] / share``, whether its columns are a range or not."""

from __future__ import annotations

import numpy as np
import pytest

from isf_robot.core.jit import compiled
from isf_robot.core.shares import gather_rows


@pytest.mark.parametrize("blocks", [(slice(0, 3), slice(3, 7)), (slice(0, 7, 2), slice(1, 7, 2)),
                                    (slice(4, 7), slice(3, None, -1)), (slice(0, 7), slice(7, 7)),
                                    # (columns whose ends look like a range's, not a range)
                                    (np.array([0, 2, 1, 3]), np.array([4, 4, 6]))])
@pytest.mark.parametrize("run", [gather_rows, compiled(gather_rows)], ids=["plain", "compiled"])
def test_gather_rows_takes_each_agents_columns_divided_by_its_shares(blocks, run) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(5)
    k, m = 9, 7
    h, lf, gn, lg = rng.normal(size=k), rng.normal(size=k), rng.normal(size=k), rng.normal(size=(k, m))
    each = [np.arange(m, dtype=np.intp)[b] for b in blocks]
    picks = [np.sort(rng.choice(k, 5, replace=False)).astype(np.intp) for _ in blocks]
    rows, cols = np.concatenate(picks), np.concatenate(each)
    ends = np.cumsum([p.size for p in picks]).astype(np.intp)
    col_ends = np.cumsum([c.size for c in each]).astype(np.intp)
    share = rng.uniform(0.25, 1.0, rows.size)
    scaled = np.array([True, False][: len(blocks)])
    out = np.empty(rows.size), np.empty(rows.size), np.empty(rows.size), np.empty(sum(
        p.size * c.size for p, c in zip(picks, each)))
    run(h, lf, lg, gn, rows, ends, cols, col_ends, share, scaled, *out)
    want, r0 = [], 0
    for a, (p, c) in enumerate(zip(picks, each)):
        block = lg[p][:, c]
        want.append((block / share[r0: r0 + p.size, None] if scaled[a] else block).ravel())
        r0 += p.size
    np.testing.assert_array_equal(out[3], np.concatenate(want))
    np.testing.assert_array_equal(out[0], h[rows])
    np.testing.assert_array_equal(out[1], lf[rows])
    np.testing.assert_array_equal(out[2], gn[rows])
