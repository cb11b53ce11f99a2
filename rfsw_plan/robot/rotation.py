"""SciPy's rotations without the start-up of ``scipy.spatial``.

:class:`Rotation` is the part of :class:`scipy.spatial.transform.Rotation` that the plan
readers and the controller formats use (``from_matrix``, ``from_rotvec``, ``from_quat``,
``as_matrix``, ``as_rotvec``, ``as_quat``, ``as_euler``, ``inv``, ``magnitude``, composition
``*``, indexing, ``len``). Its numbers are SciPy's: each method calls the same compiled function
SciPy's class calls for NumPy arrays (its Cython backend,
``scipy.spatial.transform._rotation_cy``), with the same arguments, so a program or a stream
is the same bytes either way. Only the loading differs: importing ``scipy.spatial.transform``
runs the ``scipy.spatial`` package first (k-d trees, Qhull, distances, sparse matrices, linear
algebra and special functions, about 0.25 s of CPU at every start of ``export`` and ``check``,
issue 41); this module loads the backend's extension file alone, under its own name, so a later
``import scipy.spatial`` uses that same module.
Its initialisation takes two names from ``scipy._lib._util``, whose import runs SciPy's
array-API layer (and ``numpy.f2py``), as long again: a stand-in lends them while it loads
(:func:`_util_stand_in`).

Where the backend is not found as this SciPy lays it out, or does not answer the calls
:class:`Rotation` makes (checked once on the identity), every method gives SciPy's public
class instead (same numbers, the slower start).
``tests/test_rotation.py`` compares both, bit for bit, on random rotations.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import sys
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

#: The module of SciPy's compiled rotation functions (SciPy >= 1.16).
BACKEND = "scipy.spatial.transform._rotation_cy"
#: The functions of it that :class:`Rotation` calls.
BACKEND_FUNCTIONS = ("from_matrix", "from_rotvec", "from_quat", "as_matrix", "as_rotvec",
                     "as_quat", "as_euler", "compose_quat", "inv", "magnitude")
_LOADED: list[Any] = []


def backend() -> Any:
    """SciPy's rotation backend module, or None where it cannot be loaded alone (then
    :class:`Rotation` is SciPy's public class)."""
    if not _LOADED:
        _LOADED.append(_load())
    return _LOADED[0]


def _load() -> Any:
    mod = sys.modules.get(BACKEND)
    if mod is None:
        try:
            import scipy

            folder = Path(scipy.__file__).parent / "spatial" / "transform"
            path = next((folder / f"_rotation_cy{s}" for s in importlib.machinery.EXTENSION_SUFFIXES
                         if (folder / f"_rotation_cy{s}").is_file()), None)
            if path is None:
                return None
            loader = importlib.machinery.ExtensionFileLoader(BACKEND, str(path))
            spec = importlib.util.spec_from_file_location(BACKEND, path, loader=loader)
            if spec is None:
                return None
            mod = importlib.util.module_from_spec(spec)
            sys.modules[BACKEND] = mod  # the one copy: scipy.spatial imports this one later
            stand_in = _util_stand_in()
            try:
                loader.exec_module(mod)
            except BaseException:
                del sys.modules[BACKEND]
                raise
            finally:
                if stand_in is not None and sys.modules.get(UTIL) is stand_in:
                    del sys.modules[UTIL]
        except (ImportError, OSError):
            return None
    return mod if _answers(mod) else None


#: The SciPy module the backend's initialisation imports from: ``check_random_state`` and the
#: decorator ``_transition_to_rng``, both for its ``random`` only (which :class:`Rotation`
#: does not offer).
UTIL = "scipy._lib._util"


def _util_stand_in() -> Any:
    """While the backend loads, a stand-in for :data:`UTIL` (None where it is loaded already):
    importing that module runs SciPy's array-API layer, which through NumPy's lazy attributes
    imports ``numpy.f2py`` and ``numpy.random`` (about 0.13 s of CPU, as long as the rest of
    the load). The stand-in's two names defer to SciPy's own, imported at the first call of
    the backend's ``random`` (the same function, decorated by SciPy's decorator then, so
    ``scipy.spatial``'s ``Rotation.random`` is unchanged); the caller removes the stand-in
    once the backend is loaded, so any later import of :data:`UTIL` gets SciPy's module."""
    if UTIL in sys.modules:
        return None
    import functools
    import types

    def check_random_state(seed: Any) -> Any:
        """SciPy's ``check_random_state`` (imported on first use)."""
        from scipy._lib._util import check_random_state as scipy_check

        return scipy_check(seed)

    def _transition_to_rng(*args: Any, **kwargs: Any) -> Any:
        """SciPy's decorator, applied at the decorated function's first call."""
        def decorate(fun: Any) -> Any:
            done: list[Any] = []

            @functools.wraps(fun)
            def run(*a: Any, **k: Any) -> Any:
                if not done:
                    from scipy._lib._util import _transition_to_rng as scipy_transition

                    done.append(scipy_transition(*args, **kwargs)(fun))
                return done[0](*a, **k)
            return run
        return decorate

    stand_in = types.ModuleType(UTIL, "stand-in while the rotation backend loads")
    stand_in.check_random_state = check_random_state  # type: ignore[attr-defined]
    stand_in._transition_to_rng = _transition_to_rng  # type: ignore[attr-defined]
    sys.modules[UTIL] = stand_in
    return stand_in


def _answers(mod: Any) -> bool:
    """Whether ``mod`` has every function of :data:`BACKEND_FUNCTIONS`, takes the arguments
    :class:`Rotation` passes and turns the identity into the identity (a SciPy whose backend
    changed its calls gets the public class, not an error)."""
    try:
        eye = mod.from_matrix(np.eye(3)[None], assume_valid=False)
        got = [mod.as_matrix(eye)[0], mod.as_rotvec(eye, degrees=False)[0],
               mod.as_quat(eye, canonical=False, scalar_first=False)[0],
               mod.as_euler(eye, "ZYX", degrees=False, suppress_warnings=False)[0],
               mod.magnitude(eye), mod.inv(eye)[0], mod.compose_quat(eye, eye)[0],
               mod.from_quat(eye, normalize=True, copy=False, scalar_first=False)[0],
               mod.from_rotvec(np.zeros((1, 3)), degrees=False)[0]]
        want = [np.eye(3), np.zeros(3), eye[0], np.zeros(3), np.zeros(1), eye[0], eye[0],
                eye[0], eye[0]]
        return bool(np.allclose(eye, [[0.0, 0.0, 0.0, 1.0]]) and all(
            np.shape(g) == np.shape(w) and np.allclose(g, w) for g, w in zip(got, want,
                                                                              strict=True)))
    except Exception:  # any failure of another SciPy's backend: the public class
        return False


def _public() -> Any:
    from scipy.spatial.transform import Rotation as SciPyRotation

    return SciPyRotation


def _float(x: ArrayLike) -> FloatArray:
    return np.asarray(x, dtype=np.float64)


class Rotation:
    """Rotations in 3-D as SciPy's :class:`~scipy.spatial.transform.Rotation` holds them: unit
    quaternions (x, y, z, w), shape (m, 4), one rotation or a stack (module docstring)."""

    __slots__ = ("_quat", "_single")

    def __init__(self, quat: FloatArray, normalize: bool = True) -> None:
        """From quaternions (x, y, z, w), shape (4,) or (m, 4); ``normalize`` divides by
        their norms (SciPy's ``Rotation(quat, normalize)``)."""
        quat = _float(quat)
        self._single = quat.ndim == 1
        if self._single:
            quat = quat[None]
        self._quat = backend().from_quat(quat, normalize=normalize, copy=False,
                                         scalar_first=False)

    @classmethod
    def _raw(cls, quat: FloatArray) -> Rotation:
        rot = cls.__new__(cls)
        rot._single = quat.ndim == 1
        rot._quat = quat[None] if rot._single else quat
        return rot

    @classmethod
    def from_matrix(cls, matrix: ArrayLike) -> Rotation:
        """From rotation matrices, shape (3, 3) or (m, 3, 3) (orthogonalised as SciPy does)."""
        b = backend()
        if b is None:
            return _public().from_matrix(matrix)
        return cls._raw(b.from_matrix(_float(matrix), assume_valid=False))

    @classmethod
    def from_rotvec(cls, rotvec: ArrayLike) -> Rotation:
        """From rotation vectors [rad], shape (3,) or (m, 3)."""
        b = backend()
        if b is None:
            return _public().from_rotvec(rotvec)
        return cls._raw(b.from_rotvec(_float(rotvec), degrees=False))

    @classmethod
    def from_quat(cls, quat: ArrayLike) -> Rotation:
        """From quaternions (x, y, z, w), shape (4,) or (m, 4), normalised."""
        if backend() is None:
            return _public().from_quat(quat)
        return cls(_float(quat), normalize=True)

    def _out(self, a: FloatArray) -> Any:
        return a[0] if self._single else a

    def as_matrix(self) -> FloatArray:
        """Rotation matrices, shape (3, 3) or (m, 3, 3)."""
        return self._out(backend().as_matrix(self._quat))

    def as_rotvec(self) -> FloatArray:
        """Rotation vectors [rad], shape (3,) or (m, 3)."""
        return self._out(backend().as_rotvec(self._quat, degrees=False))

    def as_quat(self) -> FloatArray:
        """Quaternions (x, y, z, w) as stored, shape (4,) or (m, 4)."""
        return self._out(backend().as_quat(self._quat, canonical=False,
                                           scalar_first=False))

    def as_euler(self, seq: str) -> FloatArray:
        """Euler angles [rad] in the axis sequence ``seq`` (``"ZYX"``: intrinsic), shape (3,)
        or (m, 3)."""
        return self._out(backend().as_euler(self._quat, seq, degrees=False,
                                            suppress_warnings=False))

    def magnitude(self) -> Any:
        """Rotation angles [rad], a float or shape (m,)."""
        return self._out(backend().magnitude(self._quat))

    def inv(self) -> Rotation:
        """The inverse rotations."""
        return self._raw(self._out(backend().inv(self._quat)))

    def __mul__(self, other: Rotation) -> Rotation:
        """The composition ``self * other`` (``other`` applied first), normalised."""
        quat = backend().compose_quat(self._quat, other._quat)
        return Rotation(quat[0] if self._single and other._single else quat, normalize=True)

    def __getitem__(self, index: Any) -> Rotation:
        """The rotations at ``index`` (an int, a slice, integer or boolean arrays)."""
        if self._single:
            raise TypeError("Single rotation is not subscriptable.")
        if isinstance(index, np.ndarray) and np.issubdtype(index.dtype, np.integer):
            return Rotation(np.take(self._quat, index, axis=0), normalize=False)
        return Rotation(self._quat[index, ...], normalize=False)

    def __len__(self) -> int:
        if self._single:
            raise TypeError("Single rotation has no len().")
        return len(self._quat)
