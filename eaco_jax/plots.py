"""Figures users expect: convergence curves, tours, joint-angle trajectories.

Every function draws one matplotlib figure: given a ``path`` it writes a PNG there, closes
the figure and returns the path; without one (``path=None``) it returns the
:class:`matplotlib.figure.Figure` (a notebook shows it). Outside Jupyter the Agg backend is used,
so no display is needed. Histories with a leading seed axis are drawn as the median with a
min-max band.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

if "ipykernel" not in sys.modules:  # a notebook keeps its inline backend
    matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

#: what the plot functions return: the PNG's path, or the figure when no path is given
Drawn = Any


def subplots(*args, **kwargs):
    """``plt.subplots`` on the Agg backend (no display needed)."""
    return plt.subplots(*args, **kwargs)


def save_figure(fig: plt.Figure, path: str | Path) -> Path:
    """Write ``fig`` as PNG at ``path`` (folders created) and close it."""
    return _save(fig, Path(path))


def sweep_summary(table: Any, key: str = "best_cost", by: str = "cell",
                  path: str | Path | None = None, title: str = "sweep") -> Drawn:
    """Box plot of ``key`` over seeds for every ``by`` value of a sweep table (the rows of
    ``OUT/table.json``, a list of dicts, or its path)."""
    import json

    if isinstance(table, str | Path):
        table = json.loads(Path(table).read_text())["rows"]
    groups: dict[str, list[float]] = {}
    for row in table:
        value = row.get(key)
        if value is not None and np.isfinite(value):
            groups.setdefault(str(row.get(by)), []).append(float(value))
    fig, ax = plt.subplots(figsize=(max(5.0, 0.6 * len(groups) + 2), 4.0))
    ax.boxplot(list(groups.values()) or [[np.nan]])
    ax.set_xticks(range(1, len(groups) + 1), list(groups), rotation=45, ha="right", fontsize=8)
    ax.set_xlabel(by)
    ax.set_ylabel(f"{key} over seeds")
    ax.set_title(title)
    return _save(fig, path)


def _save(fig: plt.Figure, path: str | Path | None) -> Drawn:
    if path is None:
        fig.tight_layout()
        plt.close(fig)  # not shown twice in notebooks; the returned figure still displays
        return fig
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def convergence(
    history: Mapping[str, np.ndarray],
    path: str | Path | None = None,
    *,
    title: str = "Convergence",
    ylabel: str = "cost",
    optimum: float | None = None,
    keys: Sequence[str] = ("best_cost", "iter_mean_cost"),
    evaluations_per_iteration: int | None = None,
) -> Drawn:
    """Best-so-far (and iteration mean) cost against iterations or evaluations."""
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for key in keys:
        if key not in history:
            continue
        y = np.asarray(history[key], dtype=float)
        y = np.where(np.isfinite(y), y, np.nan)
        y2 = y if y.ndim == 2 else y[None]
        x = np.arange(1, y2.shape[1] + 1)
        if evaluations_per_iteration:
            x = x * evaluations_per_iteration
        label = key.replace("_", " ")
        med = np.nanmedian(y2, axis=0)
        (line,) = ax.plot(x, med, label=label if y.ndim == 1 else f"{label} (median)")
        if y.ndim == 2 and y.shape[0] > 1:
            ax.fill_between(x, np.nanmin(y2, 0), np.nanmax(y2, 0), alpha=0.2,
                            color=line.get_color())
    if optimum is not None:
        ax.axhline(optimum, color="k", ls="--", lw=1, label=f"optimum {optimum:g}")
    ax.set_xlabel("evaluations" if evaluations_per_iteration else "iteration")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend()
    return _save(fig, path)


def tour(
    coords: np.ndarray, order: np.ndarray, path: str | Path | None = None, *,
    title: str = "Tour",
) -> Drawn:
    """A closed tour over 2-D city coordinates."""
    coords = np.asarray(coords, dtype=float)
    closed = np.append(np.asarray(order), order[0])
    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    ax.plot(coords[closed, 0], coords[closed, 1], "-", lw=1.0, color="tab:blue")
    ax.plot(coords[:, 0], coords[:, 1], "o", ms=3, color="tab:red")
    ax.plot(*coords[order[0]], "s", ms=7, color="k", label="start")
    ax.set_aspect("equal")
    ax.set_title(title)
    ax.legend(loc="best")
    return _save(fig, path)


def joint_trajectories(
    time: np.ndarray,
    angles: Mapping[str, np.ndarray],
    path: str | Path | None = None,
    *,
    title: str = "Joint angles",
    groups: Sequence[str] = ("Hip", "Knee", "Ankle"),
) -> Drawn:
    """Joint angles (degrees) against time, one panel per joint group (the paper's Figs. 3, 10).

    ``angles`` maps joint names (e.g. ``LHipPitch``) to radians over ``time``; a joint goes to
    the first group whose name it contains.
    """
    fig, axes = plt.subplots(len(groups), 1, figsize=(7.0, 2.2 * len(groups)), sharex=True)
    axes = np.atleast_1d(axes)
    for ax, group in zip(axes, groups, strict=True):
        for name, values in angles.items():
            if group.lower() in name.lower():
                ax.plot(time, np.degrees(np.asarray(values)), label=name, lw=1.2)
        ax.set_ylabel(f"{group} [deg]")
        ax.grid(alpha=0.3)
        if ax.lines:
            ax.legend(loc="upper right", fontsize=7, ncol=2)
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title(title)
    return _save(fig, path)


def pareto_front(
    points: np.ndarray,
    path: str | Path | None = None,
    *,
    xlabel: str = "objective 1",
    ylabel: str = "objective 2",
    title: str = "Pareto front",
) -> Drawn:
    """The points ``(k, 2)`` of a front, joined in order of the first objective (an empty
    front draws an empty frame that says so)."""
    fig, ax = plt.subplots(figsize=(5.6, 4.2))
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts):
        pts = pts[np.argsort(pts[:, 0], kind="stable")]
        ax.plot(pts[:, 0], pts[:, 1], "o-", ms=4)
    else:
        ax.text(0.5, 0.5, "no feasible point", ha="center", va="center",
                transform=ax.transAxes)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def planned_path(
    obstacles: Sequence[Sequence[Sequence[float]]],
    waypoints: np.ndarray,
    path: str | Path | None = None,
    *,
    title: str = "Planned path",
    optimal: np.ndarray | None = None,
    ramps: Sequence[Sequence[Sequence[float]]] = (),
    label: str = "colony best",
) -> Drawn:
    """Obstacles (filled polygons), ramps (hatched), the planned path and, if given, the
    optimal one."""
    from matplotlib.patches import Polygon

    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    for poly in ramps:
        ax.add_patch(Polygon(np.asarray(poly), closed=True, facecolor="tan", alpha=0.5,
                             hatch="//", edgecolor="0.4"))
    for poly in obstacles:
        ax.add_patch(Polygon(np.asarray(poly), closed=True, color="0.55", alpha=0.8))
    if optimal is not None:
        ax.plot(optimal[:, 0], optimal[:, 1], "--", color="tab:green", lw=1.2, label="optimal")
    w = np.asarray(waypoints)
    ax.plot(w[:, 0], w[:, 1], "-o", color="tab:blue", ms=3, lw=1.8, label=label)
    ax.plot(*w[0], "s", color="k", ms=8, label="start")
    ax.plot(*w[-1], "*", color="tab:red", ms=12, label="goal")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_title(title)
    ax.legend(loc="lower right", fontsize=8)
    return _save(fig, path)


def constrained_convergence(
    history: Mapping[str, np.ndarray],
    path: str | Path | None = None,
    *,
    f_star: float | None = None,
    title: str = "Convergence",
) -> Drawn:
    """Best feasible objective (or its error f - f*, log scale) against evaluations."""
    evals = np.asarray(history["evaluations"])
    best = np.asarray(history["best_f"], dtype=np.float64)
    feas = np.asarray(history["best_violation"]) <= 0
    fig, ax = plt.subplots(figsize=(6, 4))
    if f_star is not None:
        gap = np.where(feas, np.maximum(best - f_star, 1e-16), np.nan)
        ax.semilogy(evals, gap)
        ax.axhline(1e-4, color="gray", ls="--", lw=0.8, label="1e-4 (CEC2006 success)")
        ax.set_ylabel("best feasible f - f*")
        ax.legend()
    else:
        ax.plot(evals, np.where(feas, best, np.nan))
        ax.set_ylabel("best feasible f")
    ax.set_xlabel("evaluations")
    ax.set_title(title)
    return _save(fig, path)
