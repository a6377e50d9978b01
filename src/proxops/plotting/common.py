"""Generic figures of a SimResult (Agg backend; never imported by core)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def plot_run(result, path: Path, title: str = "") -> Path:
    """Radial/along-track trajectory, range and cumulative delta-v of one run."""
    pos = result.position
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    ax = axes[0]
    if pos.shape[1] >= 2:
        ax.plot(pos[:, 1], pos[:, 0], lw=1.2)
        ax.plot(pos[0, 1], pos[0, 0], "go", label="start")
        ax.plot(pos[-1, 1], pos[-1, 0], "rs", label="end")
        ax.plot(0, 0, "k*", ms=10, label="target")
        ax.set_xlabel("along-track y [m]")
        ax.set_ylabel("radial x [m]")
        ax.legend(loc="best", fontsize=8)
        ax.set_aspect("equal", adjustable="datalim")
    axes[1].plot(result.t, result.range_m)
    axes[1].set_xlabel("time [s]")
    axes[1].set_ylabel("range [m]")
    axes[2].plot(result.t, result.dv_cum)
    axes[2].set_xlabel("time [s]")
    axes[2].set_ylabel("cumulative Δv [m/s]")
    for a in axes:
        a.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def save(fig, path: Path, tight: bool = True) -> Path:
    """Save and close a figure; ``tight`` crops to the drawn artists (``bbox_inches="tight"``, which
    measures every text: a figure with fixed margins passes False)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight" if tight else None)
    plt.close(fig)
    return path


__all__ = ["plot_run", "save", "plt", "np"]
