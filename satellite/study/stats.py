"""Statistics of the paired satellite study: per-configuration summaries, paired reductions, CIs.

Every configuration (trigger x controller) runs from the same starts, so two configurations are
compared orbit by orbit: the reduction of orbit ``i`` is ``1 - n_cfg_i / n_ref_i`` (impulse count
``n``; the same for the total delta-v). Its mean over the orbits gets a 95 % confidence interval
from the **paired t** interval (``mean +- t_{0.975, n-1} sd / sqrt(n)``, the primary one) and a
percentile **bootstrap** interval (10,000 resamples of the orbits, fixed seed) beside it as a check
that does not lean on normality. Only orbits that both configurations flew to the end (no run
stopped by a band exit, as the periodic baseline's runs do) enter a comparison; how many did is
reported as ``n``. The *physical* comparison (:func:`paired_physical`) counts both runs of a pair only
up to the earlier of their first surface contacts: the orbit is not continued through the rock.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["paired_t_ci", "bootstrap_ci", "summarize_config", "paired_comparison", "paired_physical", "plain_change",
           "format_study"]

BOOTSTRAP_RESAMPLES = 10_000


def paired_t_ci(values: Sequence[float], level: float = 0.95) -> tuple[float, float, float]:
    """Mean and two-sided t confidence interval of ``values`` (the per-orbit paired differences).

    Returns:
        ``(mean, low, high)``; ``low = high = mean`` for one value, all NaN for none.

    """
    x = np.asarray(values, dtype=float)
    if x.size == 0:
        return math.nan, math.nan, math.nan
    mean = float(x.mean())
    if x.size == 1:
        return mean, mean, mean
    from scipy.stats import t

    half = float(t.ppf(0.5 + level / 2.0, x.size - 1)) * float(x.std(ddof=1)) / math.sqrt(x.size)
    return mean, mean - half, mean + half


def bootstrap_ci(values: Sequence[float], level: float = 0.95, resamples: int = BOOTSTRAP_RESAMPLES,
                 seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean of ``values`` (orbits resampled with replacement)."""
    x = np.asarray(values, dtype=float)
    if x.size == 0:
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, x.size, size=(resamples, x.size))].mean(axis=1)
    lo, hi = np.quantile(means, [0.5 - level / 2.0, 0.5 + level / 2.0])
    return float(lo), float(hi)


def _stats(v: Sequence[float | None]) -> dict[str, float | None]:
    x = np.asarray([a for a in v if a is not None], dtype=float)
    if x.size == 0:
        return {"mean": None, "sd": None, "min": None, "max": None}
    return {"mean": float(x.mean()), "sd": float(x.std(ddof=1)) if x.size > 1 else 0.0,
            "min": float(x.min()), "max": float(x.max())}


def summarize_config(runs: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Counts, delta-v, safety (min h, band exits) and surface contacts over one configuration's orbits."""
    full = [r for r in runs if r["completed"]]
    contacts = [r["surface_contacts"] for r in runs if r.get("surface_contacts") is not None]
    clear = [r["min_pass_clearance_m"] for r in runs if r.get("min_pass_clearance_m") is not None]
    return {
        "orbits": len(runs),
        "completed": len(full),
        "triggers": _stats([r["triggers"] for r in full]),
        "total_dv": _stats([r["total_dv"] for r in full]),
        "min_h": min((r["min_h"] for r in runs), default=None),
        "band_exits": sum(max(r["band_exits"], int(r["left_band_h"] is not None)) for r in runs),
        "orbits_with_band_exit": sum(1 for r in runs if r["band_exits"] > 0 or r["left_band_h"] is not None),
        "first_band_exit_h": _stats([r["left_band_h"] for r in runs if r["left_band_h"] is not None]),
        "surface_contacts": sum(contacts),
        "orbits_with_contact": sum(1 for c in contacts if c > 0),
        "min_pass_clearance_m": min(clear, default=None),
        "first_contact_h": _stats([r["first_contact_h"] for r in runs if r.get("first_contact_h") is not None]),
        "physical_h": _stats([r.get("physical_h") for r in runs]),
        "triggers_physical": _stats([r.get("triggers_physical") for r in runs]),
        "physical_per_100h": _stats([100.0 * r["triggers_physical"] / r["physical_h"] for r in runs
                                     if r.get("physical_h")]),
        "surface_min_h_m": min((r["surface_min_h_m"] for r in runs if r.get("surface_min_h_m") is not None),
                               default=None),
        "tau_impulses": sum(r["kinds"].get("tau", 0) for r in runs),
        "min_xi_tau": min((r["min_xi_tau"] for r in runs if r.get("min_xi_tau") is not None), default=None),
        "min_inter_event_h": min((r["min_inter_event_h"] for r in runs if r["min_inter_event_h"] is not None),
                                 default=None),
        "wall_s": sum(r["wall_s"] for r in runs),
    }


def paired_comparison(runs: Sequence[Mapping[str, Any]], ref: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Per-orbit reductions of ``runs`` against ``ref`` (matched by start), mean and 95 % CIs.

    Returns:
        ``n`` (orbits both flew to the end), and for ``triggers`` and ``total_dv``: ``mean``,
        ``ci_t`` (paired t), ``ci_bootstrap``, ``fewer`` (orbits where ``runs`` needed less).

    """
    by_start = {(r["seed"], r["inclination_deg"]): r for r in ref}
    matched = [(r, by_start[k]) for r in runs if (k := (r["seed"], r["inclination_deg"])) in by_start]
    pairs = [(a, b) for a, b in matched if a["completed"] and b["completed"]]
    out: dict[str, Any] = {"n": len(pairs)}
    for key in ("triggers", "total_dv"):
        out[key] = _reduction([(a[key], b[key]) for a, b in pairs])
    out["physical"] = paired_physical(matched)
    return out


def _reduction(counts: Sequence[tuple[float, float]]) -> dict[str, Any]:
    """Mean per-orbit reduction ``1 - a/b`` over ``(a, b)`` pairs with ``b > 0``, its CIs and how many had ``a < b``."""
    red = [1.0 - a / b for a, b in counts if b]
    mean, lo, hi = paired_t_ci(red)
    blo, bhi = bootstrap_ci(red)
    return {"mean": None if math.isnan(mean) else mean, "ci_t": None if math.isnan(lo) else [lo, hi],
            "ci_bootstrap": None if math.isnan(blo) else [blo, bhi], "fewer": sum(1 for v in red if v > 0),
            "n": len(red)}


def paired_physical(pairs: Sequence[tuple[Mapping[str, Any], Mapping[str, Any]]]) -> dict[str, Any]:
    """Paired reductions over each pair's physical flight: both runs up to the earlier of their ends.

    A run's physical flight ends at its first surface contact (or where it stopped: its last time,
    or a band exit); the pair's horizon is the earlier of the two ends, and both runs' impulses
    before it (``impulses_physical``, ``[t_h, |dv|]``) are counted. Nothing after a contact enters.

    Returns:
        ``n`` (pairs with a horizon > 0), ``horizon_h`` (mean, sd, min, max), and for ``triggers``
        and ``total_dv`` the reduction as :func:`paired_comparison` gives it (pairs whose reference
        fired before the horizon).

    """
    rows = []
    for a, b in pairs:
        if a.get("impulses_physical") is None or b.get("impulses_physical") is None:
            continue
        end = min(a["physical_h"], b["physical_h"])
        if end <= 0.0:
            continue
        ia = [dv for t, dv in a["impulses_physical"] if t < end]
        ib = [dv for t, dv in b["impulses_physical"] if t < end]
        rows.append((end, len(ia), len(ib), sum(ia), sum(ib)))
    return {"n": len(rows), "horizon_h": _stats([r[0] for r in rows]),
            "triggers": _reduction([(r[1], r[2]) for r in rows]),
            "total_dv": _reduction([(r[3], r[4]) for r in rows])}


def _f(v: Any, fmt: str) -> str:
    return "-" if v is None else format(v, fmt)


def _word(r: float) -> str:
    return f"{100 * abs(r):.1f} % {'fewer' if r > 0 else 'more'}" if round(100 * r, 1) else "0.0 %"


def plain_change(c: Mapping[str, Any] | None, noun: str = "") -> str:
    """A paired reduction in words: ``"7.4 % more (95 % CI 2.5 % to 12.2 % more)"``.

    ``c``: a reduction from :func:`paired_comparison` (``mean`` and ``ci_t`` of ``1 - a/b``); a positive
    reduction is "fewer", a negative one "more" (``a`` needed more than ``b``). ``noun`` follows the
    first figure (e.g. ``"impulses"``).
    """
    if not c or c["mean"] is None:
        return "-"
    lo, hi = c["ci_t"]
    head = _word(c["mean"]) + (f" {noun}" if noun else "")
    if lo == hi:
        return head
    if lo > 0 or hi < 0:  # one sign: name it once
        a, b = sorted((abs(lo), abs(hi)))
        return f"{head} (95 % CI {100 * a:.1f} % to {100 * b:.1f} % {'fewer' if lo > 0 else 'more'})"
    return f"{head} (95 % CI {_word(lo)} to {_word(hi)})"


def format_study(doc: Mapping[str, Any]) -> str:
    """The study as two text tables: configurations, then paired comparisons (reductions, 95 % t CI)."""
    lines = [f"{'configuration':<24} {'orbits':>6} {'triggers mean (sd)':>20} {'dv [m/s]':>9} {'min h':>9} "
             f"{'exits':>5} {'contacts':>8} {'tau':>5} {'min Xi_tau':>10} {'to contact [h]':>14} "
             f"{'per 100 h before':>16}"]
    for c in doc["configs"]:
        s = c["summary"]
        t, dv = s["triggers"], s["total_dv"]
        trig = f"{_f(t['mean'], '.1f')} ({_f(t['sd'], '.1f')})"
        ph, rate = s.get("physical_h") or {}, s.get("physical_per_100h") or {}
        lines.append(f"{c['label']:<24} {s['completed']:>3}/{s['orbits']:<2} {trig:>20} {_f(dv['mean'], '9.3f')} "
                     f"{_f(s['min_h'], '9.1f')} {s['orbits_with_band_exit']:>5} {s['surface_contacts']:>8} "
                     f"{s['tau_impulses']:>5} {_f(s['min_xi_tau'], '10.3g')} {_f(ph.get('mean'), '14.0f')} "
                     f"{_f(rate.get('mean'), '16.2f')}")
    lines.append("(a tau impulse fires only where Xi_tau = (1 + dtau_p/dt)/2 <= 0, i.e. dtau_p/dt <= -1; "
                 "'to contact': mean physical flight, to the first surface contact or the run's end)")
    if doc["comparisons"]:
        lines += ["", "a vs b, paired by start: impulses of a against b, 95 % paired t CI",
                  "  physical: both runs up to the earlier of their first surface contacts (or ends)",
                  "  whole run: orbits both flew to the end, flight through the body included"]
        for c in doc["comparisons"]:
            ph = c.get("physical")
            lines.append(f"{c['a']} vs {c['b']}")
            if ph:
                hz = ph["horizon_h"]
                lines.append(f"  physical  (n {ph['n']:>2}, mean horizon {_f(hz['mean'], '.0f')} h): "
                             f"{plain_change(ph['triggers'], 'impulses')}; dv {plain_change(ph['total_dv'])}")
            lines.append(f"  whole run (n {c['n']:>2}): {plain_change(c['triggers'], 'impulses')}; "
                         f"dv {plain_change(c['total_dv'])}")
    if doc.get("partial"):
        lines.append(f"(partial: {doc['orbits_done']} of {doc['orbits_total']} runs finished)")
    return "\n".join(lines)
