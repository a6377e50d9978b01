"""Input checking and conversion shared by the solver adapters (private)."""

from __future__ import annotations

import importlib

import numpy as np
import scipy.sparse as sp

from proxops.errors import ProxopsError, input_error


def import_solver(module: str, package: str):
    """Import a solver module lazily, with an install hint when it is missing."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:  # pragma: no cover - all solvers are project dependencies
        raise ProxopsError(
            f"solver package {package!r} is not installed ({exc}); install it with "
            f"`pip install {package}` or choose another solver"
        ) from exc


def vector(name: str, value, size: int, fill: float | None = None, allow_inf: bool = False,
           allow_nan: bool = False) -> np.ndarray:
    """1-D float64 copy of ``value`` with ``size`` entries.

    ``None`` gives a vector of ``fill`` (an error when fill is None); a scalar is
    broadcast. NaN is refused unless ``allow_nan`` (the adapters then report
    NUMERICAL_ERROR at solve time); +-inf only when ``allow_inf``.
    """
    if value is None:
        if fill is None:
            raise input_error(name, None, f"a vector of {size} numbers is required")
        return np.full(size, float(fill))
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(size, float(arr))
    arr = np.array(arr.reshape(-1) if arr.ndim == 2 and 1 in arr.shape else arr, dtype=float)
    if arr.ndim != 1 or arr.shape[0] != size:
        raise input_error(f"{name}.shape", tuple(np.shape(value)), f"must be ({size},)")
    if not allow_nan and np.isnan(arr).any():
        raise input_error(name, "NaN", "entries must be numbers (bounds may be +-inf)")
    if not allow_inf and np.isinf(arr).any():
        raise input_error(name, "inf", "entries must be finite")
    return arr


def dense_matrix(name: str, value, shape: tuple[int, int], allow_nonfinite: bool = False) -> np.ndarray:
    """C-contiguous float64 dense copy of a dense or sparse matrix with a fixed shape."""
    arr = value.toarray() if sp.issparse(value) else np.asarray(value, dtype=float)
    if arr.ndim != 2 or arr.shape != shape:
        raise input_error(f"{name}.shape", tuple(np.shape(arr)), f"must be {shape}")
    if not allow_nonfinite and not np.isfinite(arr).all():
        raise input_error(name, "non-finite entry", "matrix entries must be finite")
    return np.ascontiguousarray(arr, dtype=float)


def csc_matrix(name: str, value, shape: tuple[int, int], upper: bool = False,
               allow_nonfinite: bool = False) -> sp.csc_matrix:
    """Canonical CSC float64 copy (sorted indices, no duplicates); ``upper`` keeps the upper triangle."""
    if value is None:
        mat = sp.csc_matrix(shape, dtype=float)
    elif sp.issparse(value):
        mat = sp.csc_matrix(value, dtype=float, copy=True)
    else:
        arr = np.asarray(value, dtype=float)
        if arr.ndim != 2:
            raise input_error(f"{name}.shape", tuple(arr.shape), f"must be {shape}")
        mat = sp.csc_matrix(arr)
    if mat.shape != shape:
        raise input_error(f"{name}.shape", tuple(mat.shape), f"must be {shape}")
    if upper:
        mat = sp.triu(mat, format="csc")
    mat.sum_duplicates()
    mat.sort_indices()
    if not allow_nonfinite and not np.isfinite(mat.data).all():
        raise input_error(name, "non-finite entry", "matrix entries must be finite")
    return mat


def same_pattern(a: sp.csc_matrix, b: sp.csc_matrix) -> bool:
    """True when two canonical CSC matrices have identical sparsity patterns."""
    return (
        a.shape == b.shape
        and a.nnz == b.nnz
        and np.array_equal(a.indptr, b.indptr)
        and np.array_equal(a.indices, b.indices)
    )


def keep_columns(M: sp.csc_matrix, columns: np.ndarray, rows: np.ndarray | None = None) -> sp.csc_matrix:
    """The columns ``columns`` (increasing indices) of a canonical CSC matrix, and only its rows
    ``rows`` (increasing) when given; canonical CSC."""
    starts = M.indptr[columns]
    lengths = M.indptr[columns + 1] - starts
    ends = np.cumsum(lengths)
    take = np.repeat(starts - (ends - lengths), lengths) + np.arange(ends[-1] if len(ends) else 0)
    indices, n_rows = M.indices[take], M.shape[0]
    if rows is not None:
        new_row = np.full(n_rows, -1, dtype=M.indices.dtype)
        new_row[rows] = np.arange(len(rows), dtype=M.indices.dtype)
        indices = new_row[indices]
        kept = indices >= 0
        column = np.repeat(np.arange(len(columns)), lengths)
        take, indices = take[kept], indices[kept]
        lengths = np.bincount(column[kept], minlength=len(columns))
        n_rows = len(rows)
    indptr = np.zeros(len(columns) + 1, dtype=M.indptr.dtype)
    np.cumsum(lengths, out=indptr[1:])
    return sp.csc_matrix((M.data[take], indices, indptr), shape=(n_rows, len(columns)))


def symmetric_upper_product(U: sp.csc_matrix, x: np.ndarray) -> np.ndarray:
    """``P x`` for the symmetric P whose upper triangle (with the diagonal) is stored in ``U``."""
    return U @ x + U.T @ x - U.diagonal() * x


def refill_same_pattern(stored: sp.csc_matrix, value) -> sp.csc_matrix | None:
    """``stored`` with its entries overwritten by ``value``'s when ``value`` is a CSC float64 matrix
    in canonical form with exactly ``stored``'s shape and sparsity pattern (an in-place update of a
    fixed-pattern problem: the same entries :func:`csc_matrix` would give, without building a new
    matrix, 0.1-0.2 ms a call); None otherwise (the caller converts and checks ``value``)."""
    if not (sp.issparse(value) and value.format == "csc" and value.dtype == np.float64):
        return None
    source = getattr(stored, "_pattern_source", None)  # read-only index arrays already found equal
    if not (source is not None and source[0] is value.indices and source[1] is value.indptr
            and value.shape == stored.shape):
        if not (value.has_canonical_format and same_pattern(value, stored)):
            return None
        if not (value.indices.flags.writeable or value.indptr.flags.writeable):
            # a fixed pattern the caller shares read-only between updates (it cannot change): the next
            # update with these arrays skips the comparison (stored's own arrays are never written)
            stored._pattern_source = (value.indices, value.indptr)
    stored.data[:] = value.data
    return stored


def rows_of(name: str, A) -> int:
    """Number of rows of a matrix given densely or sparsely (0 for None)."""
    if A is None:
        return 0
    shape = A.shape if sp.issparse(A) else np.shape(A)
    if len(shape) != 2:
        raise input_error(f"{name}.shape", tuple(shape), "must be 2-D (rows, n)")
    return int(shape[0])


def first_crossed(lower: np.ndarray, upper: np.ndarray) -> int | None:
    """Index of the first entry with lower > upper (an empty, hence infeasible, row), else None.

    Crossed bounds are reported by the adapters as an INFEASIBLE status, never raised:
    they can come from state-dependent constraint data during a run.
    """
    bad = np.flatnonzero(lower > upper)
    return int(bad[0]) if bad.size else None


class BadData:
    """Tracks problem fields holding NaN (or inf in a matrix/cost) so ``solve`` reports
    NUMERICAL_ERROR instead of handing them to the solver or raising mid-run."""

    def __init__(self) -> None:
        self.fields: set[str] = set()

    def check(self, name: str, arr, allow_inf: bool = False) -> bool:
        """Record whether ``arr`` (ndarray or sparse) is usable; True when it is."""
        data = arr.data if sp.issparse(arr) else np.asarray(arr)
        good = not np.isnan(data).any() if allow_inf else bool(np.isfinite(data).all())
        if good:
            self.fields.discard(name)
        else:
            self.fields.add(name)
        return good

    def message(self) -> str | None:
        if not self.fields:
            return None
        return "non-finite problem data in " + ", ".join(sorted(self.fields)) + "; nothing was solved"
