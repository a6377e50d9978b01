"""Named state layouts: which components of a plant's measured state are what, in which unit.

A :class:`StateLayout` is a tuple of :class:`Block` (name, kind, start, stop, units). Every
plant has one (``plant.layout``); the engine stores it with the result
(``SimResult.meta["layout"]``) and the accessors ``SimResult.position`` / ``velocity`` /
``attitude`` read it, and navigation noise is drawn per block (a quaternion block gets a
small rotation, not additive noise). Block kinds:

============ ======================================== ======
kind         meaning                                   unit
============ ======================================== ======
position     position vector                           m
velocity     velocity vector                           m/s
quaternion   attitude, scalar-last Hamilton [x,y,z,w]  -
angle        planar attitude angle                     rad
rate         angular rate                              rad/s
mass         mass                                      kg
other        anything else (units given per name)      -
============ ======================================== ======
"""

from __future__ import annotations

from dataclasses import dataclass

KIND_UNITS = {"position": "m", "velocity": "m/s", "quaternion": "-", "angle": "rad", "rate": "rad/s",
              "mass": "kg", "other": "-"}


@dataclass(frozen=True)
class Block:
    """One named block ``state[start:stop]`` of kind ``kind`` (see module table)."""

    name: str
    kind: str
    start: int
    stop: int
    names: tuple[str, ...] = ()  # component names (default name_0, name_1, ...)
    unit: str = ""  # default: the kind's unit
    frame: str = ""  # frame the components are expressed in ("hill", "chief", ...; "" = none/scalar)

    def __post_init__(self):
        if self.kind not in KIND_UNITS:
            raise ValueError(f"block {self.name!r}: kind {self.kind!r} not in {sorted(KIND_UNITS)}")
        if not 0 <= self.start < self.stop:
            raise ValueError(f"block {self.name!r}: need 0 <= start < stop, got {self.start}:{self.stop}")
        if self.kind == "quaternion" and self.stop - self.start != 4:
            raise ValueError(f"block {self.name!r}: a quaternion has 4 components")
        if not self.names:
            object.__setattr__(self, "names", tuple(f"{self.name}_{i}" for i in range(self.stop - self.start)))
        if not self.unit:
            object.__setattr__(self, "unit", KIND_UNITS[self.kind])

    @property
    def slice(self) -> slice:
        return slice(self.start, self.stop)

    @property
    def size(self) -> int:
        return self.stop - self.start


@dataclass(frozen=True)
class StateLayout:
    """The blocks of a state vector of length ``n_x`` (blocks may leave gaps; they may not overlap)."""

    n_x: int
    blocks: tuple[Block, ...]

    def __post_init__(self):
        used = [False] * self.n_x
        for b in self.blocks:
            if b.stop > self.n_x:
                raise ValueError(f"block {b.name!r} ends at {b.stop} > n_x = {self.n_x}")
            for i in range(b.start, b.stop):
                if used[i]:
                    raise ValueError(f"block {b.name!r} overlaps another block at index {i}")
                used[i] = True

    # --- look-up ----------------------------------------------------------------
    def block(self, name: str) -> Block:
        for b in self.blocks:
            if b.name == name:
                return b
        raise KeyError(f"no block {name!r} in layout ({', '.join(b.name for b in self.blocks)})")

    def first(self, kind: str) -> Block | None:
        """The first block of ``kind`` (None when there is none)."""
        for b in self.blocks:
            if b.kind == kind:
                return b
        return None

    def span(self, kind: str) -> tuple[int, int] | None:
        """``(start, stop)`` of the first block of ``kind``."""
        b = self.first(kind)
        return None if b is None else (b.start, b.stop)

    @property
    def names(self) -> list[str]:
        """One name per state component (``x_<i>`` for components in no block)."""
        out = [f"x_{i}" for i in range(self.n_x)]
        for b in self.blocks:
            out[b.start:b.stop] = b.names
        return out

    @property
    def units(self) -> list[str]:
        out = ["-"] * self.n_x
        for b in self.blocks:
            out[b.start:b.stop] = [b.unit] * b.size
        return out

    @property
    def frames(self) -> list[str]:
        out = [""] * self.n_x
        for b in self.blocks:
            out[b.start:b.stop] = [b.frame] * b.size
        return out

    def column_names(self, prefix: str = "") -> list[str]:
        """Self-explaining table column names, one per component: ``prefix + name_frame_unit``
        (e.g. ``x_hill_m``, ``vy_hill_mps``, ``est_theta_rad``, ``q_w``); see :func:`column_name`."""
        return [prefix + column_name(n, f, u) for n, f, u in zip(self.names, self.frames, self.units)]

    # --- persistence --------------------------------------------------------------
    def to_dict(self) -> dict:
        return {"n_x": self.n_x, "blocks": [{"name": b.name, "kind": b.kind, "start": b.start, "stop": b.stop,
                                             "names": list(b.names), "unit": b.unit, "frame": b.frame}
                                            for b in self.blocks]}

    @classmethod
    def from_dict(cls, d: dict) -> "StateLayout":
        return cls(int(d["n_x"]), tuple(Block(b["name"], b["kind"], int(b["start"]), int(b["stop"]),
                                              tuple(b.get("names", ())), b.get("unit", ""), b.get("frame", ""))
                                        for b in d["blocks"]))

    @classmethod
    def from_slices(cls, n_x: int, position: tuple[int, int] = (0, 3), velocity: tuple[int, int] = (3, 6)) -> "StateLayout":
        """Layout with only a position and a velocity block (results saved before layouts existed)."""
        return cls(n_x, (Block("position", "position", *position), Block("velocity", "velocity", *velocity)))


# unit -> column-name suffix (ASCII, no slashes: pandas/Parquet/MATLAB-safe); "-" (dimensionless) has none
UNIT_SUFFIX = {"m": "m", "m/s": "mps", "m/s^2": "mps2", "rad": "rad", "rad/s": "radps", "rad/s^2": "radps2",
               "kg": "kg", "N": "N", "N m": "Nm", "s": "s", "-": "", "count": "", "flag": ""}


def column_name(name: str, frame: str = "", unit: str = "-") -> str:
    """``name_frame_unitsuffix`` with empty parts dropped: ("vy", "hill", "m/s") -> ``vy_hill_mps``."""
    suffix = UNIT_SUFFIX.get(unit, unit.replace("/", "p").replace("^", "").replace(" ", ""))
    return "_".join(part for part in (name, frame, suffix) if part)


def translational_layout() -> StateLayout:
    """Hill/RTN relative state ``[x, y, z, vx, vy, vz]`` (m, m/s)."""
    return StateLayout(6, (Block("position", "position", 0, 3, ("x", "y", "z"), frame="hill"),
                           Block("velocity", "velocity", 3, 6, ("vx", "vy", "vz"), frame="hill")))


def make_control_layout(names: tuple[str, ...], units: tuple[str, ...], frame: str = "") -> StateLayout:
    """Layout of a plant's control input ``u`` (one ``other`` block per component, with its unit).
    A unit ``"kind"`` is resolved when a run is recorded: m/s for impulse commands, m/s^2 for
    accelerations (:class:`proxops.contracts.Command`)."""
    return StateLayout(len(names), tuple(Block(n, "other", i, i + 1, (n,), u, frame)
                                         for i, (n, u) in enumerate(zip(names, units))))


# translational plants: the Hill delta-v or acceleration of the command (see control_layout)
HILL_CONTROL = make_control_layout(("ux", "uy", "uz"), ("kind",) * 3, "hill")


HILL_LAYOUT = translational_layout()
