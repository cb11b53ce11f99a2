"""``rfsw_plan.robot.rotation.Rotation`` gives SciPy's numbers bit for bit (it calls SciPy's own
compiled backend, loaded without the ``scipy.spatial`` package), and so does its fallback to
SciPy's public class; a process that uses it never loads ``scipy.spatial``'s package (issue 41:
the start of ``export`` and ``check``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation as SciPy

from rfsw_plan.robot import rotation
from rfsw_plan.robot.rotation import Rotation

PACKAGE = Path(rotation.__file__).resolve().parents[1]


def _matrices(n: int, seed: int) -> np.ndarray:
    """Random rotations with the hard cases: the identity, half turns about each axis and a
    random axis, tiny angles, and matrices a few ulps off orthogonal (as a forward kinematics
    gives them); as non-contiguous (n, 3, 3) views of (n, 4, 4) poses."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    R = SciPy.from_quat(q).as_matrix()
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    special = [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]),
               np.diag([-1.0, -1.0, 1.0]), SciPy.from_rotvec(np.pi * axis).as_matrix(),
               SciPy.from_rotvec(1e-9 * axis).as_matrix(),
               SciPy.from_rotvec((np.pi - 1e-9) * axis).as_matrix()]
    R = np.concatenate([R, np.array(special)])
    R = R + 1e-15 * rng.normal(size=R.shape)
    T = np.zeros((len(R), 4, 4))
    T[:, :3, :3] = R
    T[:, 3, 3] = 1.0
    return T[:, :3, :3]


def _same(a, b) -> None:
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype
    assert np.array_equal(a.view(np.uint64), b.view(np.uint64))  # bit for bit (-0.0 too)


@pytest.fixture(params=["backend", "public"])
def Rot(request, monkeypatch):
    """The class as loaded here, and with the backend unavailable (SciPy's public class)."""
    if request.param == "public":
        monkeypatch.setattr(rotation, "_LOADED", [None])
    else:
        assert rotation.backend() is not None  # this SciPy's layout is the one loaded alone
    return Rotation


def test_every_method_gives_scipys_bits(Rot) -> None:
    M = _matrices(200, 1)
    ours, theirs = Rot.from_matrix(M), SciPy.from_matrix(M)
    _same(ours.as_quat(), theirs.as_quat())
    _same(ours.as_matrix(), theirs.as_matrix())
    _same(ours.as_rotvec(), theirs.as_rotvec())
    _same(ours.magnitude(), theirs.magnitude())
    _same(ours.as_euler("ZYX"), theirs.as_euler("ZYX"))
    _same(ours.inv().as_quat(), theirs.inv().as_quat())
    other = _matrices(200, 2)
    _same((ours.inv() * Rot.from_matrix(other)).as_rotvec(),
          (theirs.inv() * SciPy.from_matrix(other)).as_rotvec())
    idx = np.array([3, 0, 3, 150, 206])
    _same((ours[idx] * Rot.from_matrix(other[idx])).magnitude(),
          (theirs[idx] * SciPy.from_matrix(other[idx])).magnitude())
    _same(ours[2:9].as_quat(), theirs[2:9].as_quat())
    assert len(ours) == len(theirs) == 207
    rv = np.random.default_rng(3).normal(size=(50, 3)) * np.linspace(0, 4, 50)[:, None]
    _same(Rot.from_rotvec(rv).as_matrix(), SciPy.from_rotvec(rv).as_matrix())
    quat = np.random.default_rng(4).normal(size=(20, 4))
    _same(Rot.from_quat(quat).as_matrix(), SciPy.from_quat(quat).as_matrix())


def test_single_rotations_are_scipys_too(Rot) -> None:
    M = _matrices(3, 5)
    a, b = Rot.from_matrix(M[0]), SciPy.from_matrix(M[0])
    _same(a.as_quat(), b.as_quat())
    _same(a.magnitude(), b.magnitude())
    _same((a.inv() * Rot.from_matrix(M[1])).as_rotvec(),
          (b.inv() * SciPy.from_matrix(M[1])).as_rotvec())
    _same((a * Rot.from_matrix(M)).as_quat(), (b * SciPy.from_matrix(M)).as_quat())
    _same(Rot.from_quat([0.1, -0.2, 0.3, 0.9]).as_matrix(),
          SciPy.from_quat([0.1, -0.2, 0.3, 0.9]).as_matrix())
    with pytest.raises(TypeError):
        a[0]


def test_using_it_never_loads_the_spatial_package() -> None:
    """A fresh process that converts, composes and reads back rotations has SciPy's rotation
    backend loaded and not ``scipy.spatial`` itself (its k-d trees, Qhull), nor
    ``scipy.sparse`` or ``scipy.linalg``; importing ``scipy.spatial`` afterwards takes the
    same backend module, and SciPy's class gives the numbers computed before, bit for bit."""
    code = ("import sys, numpy as np\n"
            "from rfsw_plan.robot.rotation import Rotation, BACKEND\n"
            "M = np.linalg.qr(np.random.default_rng(0).normal(size=(50, 3, 3)))[0]\n"
            "r = Rotation.from_matrix(M)\n"
            "q = (r.inv() * Rotation.from_matrix(M[::-1])).as_rotvec()\n"
            "print(sorted(m for m in sys.modules if m.split('.')[:2] in (['scipy', 'spatial'],"
            " ['scipy', 'sparse'], ['scipy', 'linalg'])))\n"
            "mod = sys.modules[BACKEND]\n"
            "from scipy.spatial.transform import Rotation as R\n"
            "print(R.from_matrix(np.eye(3))._backend is mod)\n"
            "print((R.from_matrix(M).inv() * R.from_matrix(M[::-1])).as_rotvec().tobytes()"
            " == q.tobytes())\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=PACKAGE.parent, timeout=120).stdout.splitlines()
    assert out == [f"[{rotation.BACKEND!r}]", "True", "True"]


def test_loading_the_backend_leaves_scipys_util_and_random_alone() -> None:
    """Issue 41: the backend loads without SciPy's ``_lib._util`` (its array-API layer and,
    through NumPy's lazy attributes, ``numpy.f2py``: a stand-in lends the two names the
    backend's ``random`` takes from it); afterwards ``scipy._lib._util`` is SciPy's own
    module, and ``Rotation.random`` gives in that process what it gives in one that imported
    ``scipy.spatial`` alone, ``rng`` and ``random_state`` both."""
    draw = ("from scipy.spatial.transform import Rotation as R\n"
            "print(R.random(3, rng=5).as_quat().tobytes().hex())\n"
            "print(R.random(2, random_state=np.random.RandomState(4)).as_quat().tobytes().hex())\n")
    code = ("import sys, numpy as np\n"
            "from rfsw_plan.robot import rotation\n"
            "assert rotation.backend() is not None\n"
            "print(sorted(m for m in ('scipy._lib._util', 'numpy.f2py') if m in sys.modules))\n"
            + draw + "print(sys.modules['scipy._lib._util'].__file__.endswith('_util.py'))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=PACKAGE.parent, timeout=120).stdout.splitlines()
    alone = subprocess.run([sys.executable, "-c", "import numpy as np\n" + draw],
                           capture_output=True, text=True, check=True, cwd=PACKAGE.parent,
                           timeout=120).stdout.splitlines()
    assert out[0] == "[]"
    assert out[1:3] == alone and len(alone) == 2
    assert out[3] == "True"


def test_a_backend_that_changed_its_calls_is_not_used() -> None:
    """SciPy's backend answers the calls :class:`Rotation` makes; one whose functions take
    other arguments or give other results (another SciPy) is refused, so the public class is
    used instead of an error."""
    import types

    assert rotation._answers(rotation.backend())

    def refuses(*args, **kwargs):
        raise TypeError("unexpected keyword argument 'assume_valid'")

    wrong = types.SimpleNamespace(**{f: refuses for f in rotation.BACKEND_FUNCTIONS})
    assert not rotation._answers(wrong)
    real = rotation.backend()
    transposed = types.SimpleNamespace(**{f: getattr(real, f) for f in rotation.BACKEND_FUNCTIONS})
    transposed.from_rotvec = lambda rotvec, degrees: real.from_rotvec(rotvec + 1.0, degrees=degrees)
    assert not rotation._answers(transposed)
