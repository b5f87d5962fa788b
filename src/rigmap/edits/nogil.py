"""Three LAPACK/BLAS calls of the GP objective that release the GIL (ours).

:class:`rigmap.edits.propagation.EditModel` fits its two GPs in two threads, which only
helps if the linear algebra runs outside the GIL. SciPy's ``lapack.dpotrf`` releases it,
but its ``lapack.dpotri`` (the inverse ``K⁻¹`` the gradient needs, the largest part of
an evaluation), ``lapack.dpotrs`` (``K⁻¹Y``) and ``blas.dsyrk`` (``ααᵀ``) hold it for
the whole call (SciPy 1.17; ``benchmarks/edits.py``'s ``gil_share``: another Python
thread ran during 0.04–0.05 of a ``dpotri`` call's time, 0.55–0.85 of this module's), so
the two fits took turns in them. Here the same routines of the same library — SciPy's
``cython_lapack`` / ``cython_blas`` function pointers, the ones numba also calls — are
called through :mod:`ctypes`, which releases the GIL around a foreign call. Same
routines, same arguments, same memory layout: the results are bit-identical to SciPy's
wrappers (``tests/test_edits_core.py``).
"""

from __future__ import annotations

import ctypes

import numpy as np
from scipy.linalg import cython_blas, cython_lapack

_INT = ctypes.POINTER(ctypes.c_int)
_DOUBLE = ctypes.POINTER(ctypes.c_double)
_CHAR = ctypes.c_char_p


def _function(module, name: str, *argtypes):
    """A ctypes function (C calling convention: the GIL is released during the call) at
    the address SciPy exports for ``name`` in ``module.__pyx_capi__``."""
    capsule = module.__pyx_capi__[name]
    get_name = ctypes.pythonapi.PyCapsule_GetName
    get_name.restype, get_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
    get_pointer = ctypes.pythonapi.PyCapsule_GetPointer
    get_pointer.restype, get_pointer.argtypes = ctypes.c_void_p, [ctypes.py_object, ctypes.c_char_p]
    return ctypes.CFUNCTYPE(None, *argtypes)(get_pointer(capsule, get_name(capsule)))


# signatures as SciPy declares them (LP64: Fortran INTEGER is a C int)
_dpotri = _function(cython_lapack, "dpotri", _CHAR, _INT, _DOUBLE, _INT, _INT)
_dpotrs = _function(cython_lapack, "dpotrs", _CHAR, _INT, _INT, _DOUBLE, _INT, _DOUBLE, _INT, _INT)
_dsyrk = _function(
    cython_blas, "dsyrk", _CHAR, _CHAR, _INT, _INT, _DOUBLE, _DOUBLE, _INT, _DOUBLE, _DOUBLE, _INT
)


def _int(value: int):
    return ctypes.byref(ctypes.c_int(int(value)))


def _double(value: float):
    return ctypes.byref(ctypes.c_double(float(value)))


def _pointer(array: np.ndarray):
    return array.ctypes.data_as(_DOUBLE)


def _fortran_square(factor: np.ndarray) -> np.ndarray:
    if not (
        isinstance(factor, np.ndarray)
        and factor.dtype == np.float64
        and factor.ndim == 2
        and factor.shape[0] == factor.shape[1]
        and factor.flags.f_contiguous
        and factor.flags.writeable
    ):
        raise ValueError("expected a writeable Fortran-ordered square float64 array")
    return factor


def potri_lower(factor: np.ndarray) -> int:
    """``K⁻¹`` into the lower triangle of ``factor`` (a Fortran-ordered lower Cholesky
    factor of ``K``), in place, as ``lapack.dpotri(factor, lower=1, overwrite_c=1)``;
    the upper triangle is left as it was. Returns LAPACK's ``info`` (0: done)."""
    factor = _fortran_square(factor)
    n, info = len(factor), ctypes.c_int(0)
    _dpotri(b"L", _int(n), _pointer(factor), _int(max(n, 1)), ctypes.byref(info))
    return info.value


def potrs_lower(factor: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``K⁻¹ b`` from a Fortran-ordered lower Cholesky factor, as
    ``lapack.dpotrs(factor, b, lower=1)`` (a new Fortran-ordered array)."""
    factor = _fortran_square(factor)
    x = np.array(b, dtype=np.float64, order="F", copy=True)
    if x.ndim != 2 or len(x) != len(factor):
        raise ValueError(f"expected b with {len(factor)} rows, got shape {x.shape}")
    n, nrhs, info = len(factor), x.shape[1], ctypes.c_int(0)
    _dpotrs(
        b"L",
        _int(n),
        _int(nrhs),
        _pointer(factor),
        _int(max(n, 1)),
        _pointer(x),
        _int(max(n, 1)),
        ctypes.byref(info),
    )
    if info.value != 0:
        raise ValueError(f"LAPACK dpotrs: illegal value in argument {-info.value}")
    return x


def syrk_lower(a: np.ndarray) -> np.ndarray:
    """``a aᵀ``'s lower triangle (the upper is 0), Fortran-ordered, as
    ``blas.dsyrk(1.0, a, lower=1)``."""
    a = np.asarray(a, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"expected a 2-D array, got shape {a.shape}")
    a = np.asfortranarray(a)
    n, k = a.shape
    c = np.zeros((n, n), order="F")
    _dsyrk(
        b"L",
        b"N",
        _int(n),
        _int(k),
        _double(1.0),
        _pointer(a),
        _int(max(n, 1)),
        _double(0.0),
        _pointer(c),
        _int(max(n, 1)),
    )
    return c
