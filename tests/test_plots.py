"""Plots are written as real PNG files from realistic inputs (single and batched histories)."""

import numpy as np

from eaco_jax import plots

PNG = b"\x89PNG\r\n\x1a\n"


def test_convergence_single_and_batched(tmp_path):
    h1 = {"best_cost": np.linspace(10, 1, 30), "iter_mean_cost": np.linspace(12, 2, 30)}
    h2 = {k: np.stack([v, v + 1]) for k, v in h1.items()}
    for i, h in enumerate((h1, h2)):
        p = plots.convergence(h, tmp_path / f"c{i}.png", optimum=1.0)
        assert p.read_bytes()[:8] == PNG and p.stat().st_size > 5000


def test_tour_and_joint_plots(tmp_path):
    rng = np.random.default_rng(0)
    coords = rng.random((12, 2))
    p = plots.tour(coords, rng.permutation(12), tmp_path / "tour.png")
    assert p.read_bytes()[:8] == PNG
    t = np.linspace(0, 2, 100)
    angles = {"LHipPitch": np.sin(t), "RKneePitch": np.cos(t), "LAnklePitch": 0.1 * t}
    q = plots.joint_trajectories(t, angles, tmp_path / "joints.png")
    assert q.read_bytes()[:8] == PNG and q.stat().st_size > 5000


def test_without_a_path_the_figure_is_returned(tmp_path):
    import matplotlib.figure

    h = {"best_cost": np.linspace(10, 1, 30)}
    fig = plots.convergence(h)
    assert isinstance(fig, matplotlib.figure.Figure) and fig.axes[0].lines
    rows = [{"cell": c, "seed": s, "best_cost": float(c == "a") + s} for c in "ab"
            for s in range(3)]
    fig = plots.sweep_summary(rows)
    assert isinstance(fig, matplotlib.figure.Figure)
    assert plots.sweep_summary(rows, path=tmp_path / "s.png").read_bytes()[:8] == PNG
