"""Generic figures of a SimResult (Agg backend; never imported by core)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

from proxops.exec.forkserver_exit import die_with_parent  # os and sys only

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


def draw_all(jobs) -> list[Path]:
    """The paths of ``jobs`` (functions of no argument that draw and save one figure each), in order: the
    jobs after the first in forked child processes while this process draws the first (Agg renders on one
    core; Figs. 11 and 12 of ``proxops cortex references`` are 0.3 s each). A job whose child did not
    finish is drawn again here, so its error is raised as usual. Without ``os.fork``: one after another."""
    import multiprocessing
    import os

    if len(jobs) < 2 or not hasattr(os, "fork") or multiprocessing.current_process().daemon:  # (no children)
        return [job() for job in jobs]
    children = [multiprocessing.get_context("fork").Process(target=_draw_in_child, args=(job, os.getpid()),
                                                            daemon=True) for job in jobs[1:]]
    try:
        for child in children:
            child.start()
        paths = [jobs[0]()]
        for child, job in zip(children, jobs[1:]):
            child.join()
            paths.append(job.path if child.exitcode == 0 else job())
        return paths
    finally:  # an error or a Ctrl-C here: no child outlives the call
        for child in children:
            if child.is_alive():
                child.terminate()
                child.join()


class Drawing:
    """One figure for :func:`draw_all`: ``fn(*args, path=path, **kwargs)`` draws and saves it to ``path``."""

    def __init__(self, fn, path: Path, *args, **kwargs):
        self.fn, self.path, self.args, self.kwargs = fn, Path(path), args, kwargs

    def __call__(self) -> Path:
        return self.fn(*self.args, path=self.path, **self.kwargs)


def _draw_in_child(job, parent_pid: int) -> None:
    """A forked child's drawing: a Ctrl-C is the parent's to handle (it ends the child), an error ends the
    child with exit code 1 and no output (the parent draws the figure again and reports it); the child ends
    with its parent (a campaign or demo worker terminated mid-figure leaves no process drawing)."""
    import os
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent_pid)
    try:
        job()
    except BaseException:  # noqa: BLE001 - reported by the parent's own attempt
        os._exit(1)
    os._exit(0)


__all__ = ["plot_run", "save", "draw_all", "Drawing", "plt", "np"]
