"""Paper B's pictures and results table: drawn from data, written whole, the paper's numbers."""

from __future__ import annotations

import numpy as np

from locoman.artifacts import write_figure
from locoman.config.skill_transfer import KmpCfg
from locoman.hqp.figures import PAPER_RMSE, ReplaySeries, replay_figure, results_table
from locoman.kmp.demos import Demos
from locoman.kmp.figures import reference_figure
from locoman.kmp.fit import fit_case
from locoman.kmp.gmr import fit_gmm, gmr
from locoman.kmp.kmp import ViaPoint


def test_results_table_puts_ours_next_to_the_papers():
    ours = {
        case: {key: [0.001 * (i + 1)] * 3 for i, key in enumerate(PAPER_RMSE["replica"])}
        for case in ("replica", "generalisation")
    }
    table = results_table(ours)
    assert "| replica | EE position x, y, z [m] | 0.1428, 0.0505, 0.0250 | 0.0010, 0.0010" in table
    assert "| generalisation | base optimal vs actual" in table and "0.4732" in table
    assert len(table.strip().splitlines()) == 2 + 8


def test_replay_figure_has_the_papers_four_rows(tmp_path):
    t = np.linspace(0.0, 2.0, 201)
    wave = np.c_[np.sin(t), np.cos(t), t]
    series = ReplaySeries(
        t, wave, wave + 0.01, wave - 0.5, wave, wave, wave, wave, wave, 1.0, np.ones(3)
    )
    fig = replay_figure(series, "test")
    assert len(fig.axes) == 12
    assert [a.get_ylabel() for a in fig.axes[::3]] == [
        "EE x world [m]",
        "EE x arm base [m]",
        "base x [m]",
        "EE vx [m/s]",
    ]
    write_figure(tmp_path / "fig.png", fig)
    assert (tmp_path / "fig.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_reference_figure_draws_both_bands_from_a_fitted_case(tmp_path):
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 4.0, 81)
    base = np.c_[np.tile(t[:, None], 3), np.ones((81, 3)), np.zeros((81, 3))]
    outs = base[None] + rng.normal(0.0, 0.01, (3, 81, 9))
    demos = Demos(t, outs[..., 0:3], outs[..., 3:6], outs[..., 6:9])
    ref = gmr(fit_gmm(np.tile(t, 3), outs.reshape(-1, 9), 4, seed=0), np.linspace(0.0, 4.0, 40))
    via = [ViaPoint.of(2.05, np.r_[2.5, 2.5, 2.5, np.full(6, np.nan)], 1e-8)]
    cfg = KmpCfg(rate_hz=100.0, covariance_regularization=40.0)
    case = fit_case(ref, via, cfg, 4.0)
    assert case.cov.shape == (len(case.cov_time_s), 9, 9)
    fig = reference_figure(demos, ref, case, "test")
    # Two bands (GMR, KMP) per output panel.
    assert all(len(a.collections) == 2 for a in fig.axes[:9])
    write_figure(tmp_path / "ref.png", fig)
    assert (tmp_path / "ref.png").stat().st_size > 10_000
