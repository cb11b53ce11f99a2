"""Corrected waypoint files: ``waypoints.csv`` (one row per timed sample) and ``plan.json``.

``waypoints.csv`` columns (units in the names, vectors in the robot base frame):

``t_s, s_mm, phase``
    Time, arc length along the seam, phase (approach, plunge, dwell, accelerate, weld,
    decelerate, retract).
``seam_x_mm, seam_y_mm, seam_z_mm``
    The seam (joint line) point the tool is at.
``x_mm, y_mm, z_mm, qw, qx, qy, qz``
    Commanded TCP pose (the fake target): FK of the planned joints.
``A_deg, B_deg, C_deg`` (KUKA, ``euler = "kuka_abc"``) or ``W_deg, P_deg, R_deg`` (FANUC,
``"fanuc_wpr"``)
    The same orientation in the maker's convention: R = Rz(A) Ry(B) Rx(C) = Rz(R) Ry(P) Rx(W).
``A1_deg ... A6_deg`` (KUKA), ``J1_deg ... J6_deg`` (FANUC, ZK-500), ``q1_deg ...`` (a robot file
without ``[controller]``)
    Planned joint values: the controller's axis values (docs/formats/units-frames.md).
``fx_N, fy_N, fz_N, mx_Nm, my_Nm, mz_Nm``
    The process wrench on the tool the plan assumes.
``off_lat_mm, off_norm_mm, off_along_mm``
    Fake-target offset along l (toward the advancing side), n (tool axis) and t (travel): the
    commanded TCP is seam + offsets. The along-track offset is the predicted pin's lag behind
    the TCP, so the loaded pin is on the row's seam point.
``dx_mm, dy_mm, dz_mm``
    Predicted TCP deflection under the wrench (the model's process deflection with the
    problem's seam reference, ``taught`` or ``absolute``).
``e_lat_mm, margin_mm``
    Predicted lateral pin error and its margin to the nearest window bound (empty outside
    plunge, dwell and welding).
``tcp_speed_mm_s, pin_speed_mm_s``
    Commanded TCP speed |d x / dt| and the predicted (loaded) pin's speed along the seam (the
    numeric model at every sample). The weld speed is the pin's: constant during ``weld``; the
    commanded TCP runs ahead of it while the traverse force (and with it the pin's lag) ramps
    up, and at the weld speed where the force is steady.
``spindle_on, spindle_rpm``
    The spindle state (1 on, 0 off) and its commanded speed: on from the plunge start (the
    spindle-start hook, at the spindle clearance above the plate), running up linearly over
    the process's ``spindle_runup_s`` while the tool stands there, at ``rotation_speed_rpm``
    until the pin is out of the plate at the end of the retract, then off.
"""

from __future__ import annotations

import contextlib
import csv
import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.files import atomic_path, write_bytes, write_figure
from rfsw_plan.numfmt import canonical_quaternion, cell, cell_many, table_bytes
from rfsw_plan.planfiles.record import PlanRecord
from rfsw_plan.planning.verify import CONTACT_PHASES
from rfsw_plan.process.seam import Seam

if TYPE_CHECKING:  # the writer's argument: a reader of the folder (export, check)
    # never imports the planner's result and its baselines (issue 41)
    from rfsw_plan.planning.result import PlanResult

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

#: Euler columns per maker convention.
EULER_COLUMNS = {"kuka_abc": ("A_deg", "B_deg", "C_deg"), "fanuc_wpr": ("W_deg", "P_deg", "R_deg")}
#: Rounding of the joint values in ``waypoints.csv`` [rad] (6 decimals of a degree, half a unit).
Q_RESOLUTION = float(np.deg2rad(0.5e-6))


def maker_euler(R: FloatArray, convention: str) -> FloatArray:
    """Maker Euler angles [rad] of rotation matrices (m, 3, 3), shape (m, 3).

    ``kuka_abc``: (A, B, C) with R = Rz(A) Ry(B) Rx(C). ``fanuc_wpr``: (W, P, R) with
    R = Rz(R) Ry(P) Rx(W) (fixed-axis x, y, z).
    """
    from rfsw_plan.robot.rotation import Rotation

    zyx = Rotation.from_matrix(R).as_euler("ZYX")  # intrinsic z, y', x'' = (A, B, C)
    if convention == "kuka_abc":
        return zyx
    if convention == "fanuc_wpr":
        return zyx[:, ::-1]
    raise InputError("robot", "euler", f"got '{convention}'", "kuka_abc or fanuc_wpr")


def waypoint_table(result: PlanResult) -> tuple[list[str], NDArray[Any]]:
    """Header and rows (object array) of ``waypoints.csv``, predicted with the plan's own
    model (:attr:`PlanResult.model`)."""
    from scipy.spatial.transform import Rotation

    model = result.model
    tr = result.trajectory
    task = result.task
    robot = model.robot
    sv = result.samples
    if sv is not None and sv.deflection is not None and len(sv.deflection) == len(tr) > 1:
        # The sample check's deflection of these samples (its numbers: the same model, joint
        # values, wrench and seam reference), with their poses from the same kinematics.
        T, dX = robot.batch_fk_jacobian(tr.q)[0], sv.deflection
    else:
        batch = model.batch(tr.q)
        T = batch.T
        dX = model.process_deflection_batch(batch, tr.wrench, task.reference)
    m = task.n_start
    sw = task.s[m:]
    fr = task.frames

    def at_s(a: FloatArray) -> FloatArray:
        return np.stack([np.interp(tr.s, sw, a[m:, i]) for i in range(a.shape[1])], axis=1)

    seam_p = at_s(fr.p)
    lat = at_s(fr.l)
    lat /= np.linalg.norm(lat, axis=1, keepdims=True)
    e_lat = np.einsum("ki,ki->k", lat, T[:, :3, 3] + dX[:, :3] - seam_p)
    # In the material: the sample check's (the plunge's start in the air is not), else by phase.
    contact = (sv.contact if sv is not None and len(sv.contact) == len(tr)
               else np.isin(tr.phase, CONTACT_PHASES))
    w = result.window
    margin = np.minimum(e_lat - w.lower, w.upper - e_lat)
    # w, x, y, z with a sign no machine's rounding flips, back in SciPy's x, y, z, w order
    quat = np.roll(canonical_quaternion(np.roll(Rotation.from_matrix(T[:, :3, :3]).as_quat(), 1,
                                                axis=1)), -1, axis=1)
    header = ["t_s", "s_mm", "phase", "seam_x_mm", "seam_y_mm", "seam_z_mm",
              "x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"]
    cols: list[NDArray[Any]] = [tr.t, tr.s * 1e3, tr.phase, *(seam_p * 1e3).T,
                                *(T[:, :3, 3] * 1e3).T, quat[:, 3], quat[:, 0], quat[:, 1],
                                quat[:, 2]]
    if result.euler in EULER_COLUMNS:
        header += list(EULER_COLUMNS[result.euler])
        euler = np.rad2deg(maker_euler(T[:, :3, :3], result.euler))
        # The branch cut: -180 and +180 deg are one angle; written as +180 on every machine.
        cols += list(np.where(np.round(euler, 6) == -180.0, 180.0, euler).T)
    header += robot.description.convention.column_names()
    cols += list(np.rad2deg(tr.q).T)
    header += ["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm", "off_lat_mm", "off_norm_mm",
               "off_along_mm", "dx_mm", "dy_mm", "dz_mm", "e_lat_mm", "margin_mm", "tcp_speed_mm_s",
               "pin_speed_mm_s", "spindle_on", "spindle_rpm"]
    cols += list(tr.wrench.T) + list((tr.offsets * 1e3).T) + list((dX[:, :3] * 1e3).T)
    cols += [np.where(contact, e_lat * 1e3, np.nan), np.where(contact, margin * 1e3, np.nan)]
    tcp_speed = np.linalg.norm(np.gradient(T[:, :3, 3], tr.t, axis=0), axis=1)
    cols += [tcp_speed * 1e3, tr.pin_speed() * 1e3]
    cols += [np.where(tr.spindle_on, "1", "0"), tr.spindle_rpm]
    rows = np.empty((len(tr), len(header)), dtype=object)
    for j, c in enumerate(cols):
        rows[:, j] = c
    return header, rows


def write_waypoints_csv(path: str | Path, result: PlanResult) -> Path:
    """Write ``waypoints.csv`` atomically (see the module docstring for the columns), with the
    deflections and errors of the model the plan was made with."""
    header, rows = waypoint_table(result)
    p = Path(path)
    columns = [_typed(rows[:, j]) for j in range(rows.shape[1])]
    with atomic_path(p) as tmp, tmp.open("w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(header)
        try:  # the numbers as cell() writes them, built as arrays (numfmt.table_bytes)
            body = table_bytes(columns, 6)
        except ValueError:  # a text cell that needs quoting: the csv module's own quoting
            body = b""
        if body or not len(rows):
            fh.flush()
            fh.buffer.write(body)
        else:
            wr.writerows(zip(*(_column(rows[:, j]) for j in range(rows.shape[1])),
                             strict=True))
    return p


def _typed(values: NDArray[Any]) -> Any:
    """One column of ``waypoints.csv`` as numbers (a float array) or text (a list of str)."""
    if len(values) and isinstance(values[0], str | np.str_):
        return [str(v) for v in values]
    return values.astype(float)


def _column(values: NDArray[Any]) -> list[str]:
    """The cells of one column of ``waypoints.csv`` (:func:`_fmt` of each, a column at once)."""
    if len(values) and isinstance(values[0], str | np.str_):
        return [_fmt(v) for v in values]
    return cell_many(values.astype(float), 6)


def _fmt(v: Any) -> str:
    """A cell of ``waypoints.csv``: text as is, numbers with 6 decimals and never ``-0.000000``
    (:func:`rfsw_plan.numfmt.cell`), empty for NaN (no value outside the contact phases)."""
    if isinstance(v, str | np.str_):
        return str(v)
    return cell(v, 6)


def write_plan_json(path: str | Path, summary: PlanRecord | dict[str, Any],
                    vouches_for: list[Path] | tuple[Path, ...] = ()) -> Path:
    """Write ``plan.json`` atomically as strict JSON (NaN and inf become null), vouching for
    the files ``vouches_for`` (:meth:`PlanRecord.write`)."""
    return PlanRecord(dict(summary)).write(path, vouches_for)


#: The files a plan folder holds (``plan.json``, the commit record, is written last).
PLAN_OUTPUTS = ("waypoints.csv", "plan.html", "plan.json", "lateral_error.png",
                "lateral_error_time.png", "tradeoff.png")
#: The plots of a plan folder, drawn after ``plan.json`` has committed the data files.
PLAN_PLOTS = ("lateral_error.png", "lateral_error_time.png", "tradeoff.png")


def write_plan_data(folder: str | Path, result: PlanResult, seam: Seam | None = None
                    ) -> list[Path]:
    """Write a plan's data files into ``folder``: ``waypoints.csv`` and ``plan.html`` (the plan
    in 3-D, built from the written ``waypoints.csv``, :mod:`rfsw_plan.planfiles.page3d`), each
    atomically.

    ``plan.json`` (the commit record that vouches for them) is not written here: the caller adds
    its own files and then calls :func:`commit_plan`, which commits them and draws the plots.
    Shared by ``rfsw-plan plan`` and :func:`rfsw_plan.write_plan`.

    Args:
        folder: The plan folder.
        result: The plan.
        seam: The problem's seam (``plan.html`` takes its frames from it, as ``rfsw-plan view``
            does); default: the plan's waypoint frames, interpolated.

    Returns:
        The written paths (``waypoints.csv``, ``plan.html``).
    """
    from rfsw_plan.planfiles.page3d import task_frames, write_plan_page

    out = Path(folder)
    csv_path = write_waypoints_csv(out / "waypoints.csv", result)
    w = result.window
    page = write_plan_page(out, result.model.robot,
                           seam.frames_at if seam is not None else task_frames(result.task),
                           (w.lower * 1e3, w.upper * 1e3), result.problem_name,
                           result.verdict().line)
    return [csv_path, page]


def write_plan_plots(folder: str | Path, result: PlanResult,
                     drawing: PlotDrawing | None = None) -> tuple[list[Path], list[str]]:
    """Draw the plan's plots (:data:`PLAN_PLOTS`) into ``folder``, each atomically.

    A plot that fails does not stop the others: it is reported, not raised (the data files are
    already committed when the plots are written).

    Args:
        folder: The plan folder.
        result: The plan.
        drawing: The plots already being drawn in another process (:class:`PlotDrawing`):
            their images are written here. None: drawn here, one after the other.

    Returns:
        The written paths, and one line per plot that was not written
        (``lateral_error.png not written (RuntimeError: ...)``).
    """
    if drawing is not None:
        drawn = drawing.images()
        if drawn is not None:
            images, failed = drawn
            return [write_bytes(Path(folder) / name, images[name]) for name in PLAN_PLOTS
                    if name in images], failed
    return _draw_plots(Path(folder), result)


def _draw_plots(out: Path, result: PlanResult, names: tuple[str, ...] = PLAN_PLOTS
                ) -> tuple[list[Path], list[str]]:
    """Draw the plots ``names`` (default: every plot, in :data:`PLAN_PLOTS` order) into
    ``out`` (the functions looked up when called); the paths drawn and one line per failed
    plot."""
    written: list[Path] = []
    failed: list[str] = []
    from rfsw_plan.planfiles.tradeoff_plot import plot_tradeoff

    for name, draw in zip(PLAN_PLOTS, (plot_lateral_error, plot_lateral_error_time,
                                       plot_tradeoff), strict=True):
        if name not in names:
            continue
        try:
            written.append(draw(out / name, result))
        except Exception as exc:  # any plot failure is a warning, never a lost data file
            why = " ".join(str(exc).split()) or "no message"
            failed.append(f"{name} not written ({type(exc).__name__}: {why})")
    return written, failed


class PlotDrawing:
    """The plan's plots drawn in a forked process while this one writes the data files.

    The plots need nothing but the plan, and drawing them (matplotlib's import, text layout
    and PNG encoding) costs more than the CSV and the page together: on a second core they are
    off the critical path. The child writes no file: it renders the images in memory
    (:func:`rfsw_plan.files.figures_in_memory`) and sends the bytes; this process writes them
    atomically after ``plan.json`` has committed the data files (:func:`commit_plan`), so the
    folder goes through the same states as when the plots are drawn here, and the images are
    the same bytes (the same functions on the same plan). Where a process cannot be forked (a
    platform without ``fork``, a daemonic process) or the child ends without an answer,
    :func:`write_plan_plots` draws them here.

    ``PlotDrawing(folder, result)`` forks with the plan. :meth:`warm` forks before the plan
    exists, so the child imports matplotlib while this process plans, and :meth:`draw` hands
    it the plan (pickled through the pipe, the same numbers); ``rfsw-plan plan`` draws that
    way.
    """

    def __init__(self, folder: str | Path | None = None, result: PlanResult | None = None
                 ) -> None:
        import multiprocessing

        self._proc: Any = None
        self._conn: Any = None
        self._request: Any = None
        if ("fork" not in multiprocessing.get_all_start_methods()
                or multiprocessing.current_process().daemon):
            return
        ctx = multiprocessing.get_context("fork")
        for stream in (sys.stdout, sys.stderr):  # or the child's exit writes them out again
            with contextlib.suppress(Exception):
                stream.flush()
        recv, send = ctx.Pipe(duplex=False)
        job_recv, job_send = ctx.Pipe(duplex=False)
        for conn in (send, job_send):
            _widen(conn)
        job = None if result is None else (Path(folder or "."), result)
        try:
            self._proc = ctx.Process(target=_draw_in_child,
                                     args=(send, recv, job_recv, job_send, job), daemon=True)
            self._proc.start()
        except OSError:  # no process to spare: draw here
            self._proc = None
            recv.close()
            job_send.close()
        else:
            self._conn = recv
            self._request = job_send if job is None else None
            if job is not None:
                job_send.close()
        finally:
            send.close()
            job_recv.close()

    @classmethod
    def warm(cls) -> PlotDrawing:
        """Fork the drawing process now, before the plan exists (it imports matplotlib
        meanwhile); :meth:`draw` gives it the plan."""
        return cls()

    def draw(self, folder: str | Path, result: PlanResult) -> PlotDrawing:
        """Hand a :meth:`warm` process the plan to draw; returns self."""
        if self._request is not None:
            try:
                self._request.send((Path(folder), result))
            except (OSError, ValueError):  # the child is gone: images() says so, draw here
                self.close()
            else:
                self._request.close()
                self._request = None
        return self

    def images(self) -> tuple[dict[str, bytes], list[str]] | None:
        """The images by file name and the failure lines, once the child has drawn them;
        None if it could not (then draw here)."""
        if self._proc is None or self._request is not None:  # not given a plan: draw here
            self.close()
            return None
        try:
            names, failed = self._conn.recv()
            return dict(names), list(failed)
        except (EOFError, OSError):  # the child died without an answer
            return None
        finally:
            self.close()

    def close(self) -> None:
        """Stop the child if it still runs (an interrupted write, a plan that failed) and
        release the pipes."""
        if self._proc is None:
            return
        if self._request is not None:
            self._request.close()
            self._request = None
        if self._proc.is_alive():
            self._proc.terminate()
        self._proc.join()
        self._conn.close()
        self._proc = None


#: The pipes' buffer [bytes] between the plan's process and its drawing process (Linux allows
#: an unprivileged process up to 1 MiB, ``/proc/sys/fs/pipe-max-size``; the default is 64 KiB).
PIPE_BYTES = 1 << 20


def _widen(conn: Any) -> None:
    """Give a pipe :data:`PIPE_BYTES` of buffer where the platform allows (Linux's
    ``F_SETPIPE_SZ``): a plan of 13 MB pickled (kr600_curved_seam's 28 000 samples) then
    crosses in 13 writes instead of 200, each waiting for the reader (the hand-off took
    33 ms, now 22-26 ms)."""
    import fcntl

    with contextlib.suppress(AttributeError, OSError, ValueError):
        fcntl.fcntl(conn.fileno(), fcntl.F_SETPIPE_SZ, PIPE_BYTES)


def import_for_drawing() -> None:
    """Import what drawing a plan needs, and what receiving it does: matplotlib, the plots'
    modules, and the modules of every class a pickled :class:`PlanResult` holds (its
    :class:`~rfsw_plan.timing.TimedTrajectory` brings SciPy's interpolation).

    A :meth:`PlotDrawing.warm` child imports these while the plan is made, not when the plan
    arrives, on the critical path (0.3 s of unpickling on zk500, almost all of it imports);
    ``rfsw-plan plan`` forks it once the planner is imported, so only matplotlib is left to
    import, but a caller that forks it earlier gets the same. ``tests/test_waypoints.py``
    checks that unpickling a plan after this imports nothing more of ours, SciPy's or
    matplotlib's."""
    import matplotlib.backends.backend_agg
    import matplotlib.figure  # noqa: F401

    import rfsw_plan.planfiles.tradeoff_plot
    import rfsw_plan.planning.result
    import rfsw_plan.timing  # noqa: F401


def _draw_in_child(conn: Any, parents_end: Any, jobs: Any, parents_jobs: Any,
                   job: tuple[Path, PlanResult] | None) -> None:
    """The forked child of :class:`PlotDrawing`: draw in memory, send (name, bytes) pairs
    and the failure lines. Without ``job`` (a warm child) it first imports what drawing needs,
    then waits for the folder and the plan on ``jobs``; the parent closing that pipe without
    a plan ends it.

    It first closes its copies of the parent's ends of the pipes: with the parent killed
    (SIGKILL), the send then fails at once (no reader left) and the wait for a plan ends (no
    writer left), so the child ends instead of blocking forever, holding the parent's terminal
    or pipes open."""
    import signal

    from rfsw_plan.files import OutputLock

    parents_end.close()
    parents_jobs.close()

    # Ctrl-C is the parent's to handle (it stops this child); SIGTERM ends it silently.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    OutputLock.close_inherited()
    if job is None:
        import_for_drawing()
        try:
            job = jobs.recv()
        except (EOFError, OSError):  # the parent planned nothing to draw, or is gone
            return
    jobs.close()
    folder, result = job
    images, failed = _draw_beside_a_helper(folder, result, conn)
    conn.send((list(images.items()), failed))
    conn.close()


#: The plots the drawing process hands to a forked helper of its own (the margin panel of
#: every written sample, the costliest), drawn while it draws the others: on two cores the
#: three plots take about the time of the two, beside the data files the planner's process
#: writes.
HELPER_PLOTS = ("lateral_error_time.png",)


def _draw_beside_a_helper(folder: Path, result: PlanResult, conn: Any = None
                          ) -> tuple[dict[str, bytes], list[str]]:
    """The images of every plot by file name (:data:`PLAN_PLOTS` order) and one line per
    failed plot, drawn in memory: :data:`HELPER_PLOTS` by a forked helper process (the same
    functions on the same plan: the same bytes), the others here meanwhile. A helper that
    cannot be forked or ends without an answer costs no plot: its plots are drawn here.

    Args:
        folder: The plan folder (the images' names).
        result: The plan.
        conn: This process's end of the pipe to its parent, closed in the helper (so the
            parent sees this process end when it ends).
    """
    from rfsw_plan.files import figures_in_memory

    helper = _fork_helper(folder, result, conn)
    mine = tuple(n for n in PLAN_PLOTS if helper is None or n not in HELPER_PLOTS)
    with figures_in_memory() as here:
        _, failed = _draw_plots(folder, result, mine)
    images = {p.name: data for p, data in here.items()}
    if helper is not None:
        got = _helper_answer(*helper)
        if got is None:  # the helper died: its plots are drawn here
            with figures_in_memory() as here:
                _, again = _draw_plots(folder, result, HELPER_PLOTS)
            got = ({p.name: data for p, data in here.items()}, again)
        images.update(got[0])
        failed += got[1]
    order = {name: k for k, name in enumerate(PLAN_PLOTS)}
    failed.sort(key=lambda line: order.get(line.split(" ", 1)[0], len(order)))
    return {n: images[n] for n in PLAN_PLOTS if n in images}, failed


def _fork_helper(folder: Path, result: PlanResult, conn: Any) -> tuple[int, int] | None:
    """Fork the helper of :func:`_draw_beside_a_helper`: its process id and the read end of
    its pipe, or None (no ``fork``, no process to spare). Until its answer is read, a SIGTERM
    (the parent stopping this process) stops the helper too."""
    import os
    import pickle
    import signal

    from rfsw_plan.files import figures_in_memory

    if not hasattr(os, "fork"):
        return None
    read_end, write_end = os.pipe()
    try:
        pid = os.fork()
    except OSError:
        os.close(read_end)
        os.close(write_end)
        return None
    if pid == 0:  # the helper: draw, send the (name, bytes) pairs and the failures, end
        code = 1
        try:
            os.close(read_end)
            if conn is not None:
                conn.close()
            with figures_in_memory() as theirs:
                _, failed = _draw_plots(folder, result, HELPER_PLOTS)
            with os.fdopen(write_end, "wb") as fh:
                fh.write(pickle.dumps(({p.name: b for p, b in theirs.items()}, failed)))
            code = 0
        finally:
            os._exit(code)  # never the drawing process's clean-up, which is not the helper's
    os.close(write_end)
    signal.signal(signal.SIGTERM, lambda *_: _stop_with(pid))
    return pid, read_end


def _helper_answer(pid: int, read_end: int) -> tuple[dict[str, bytes], list[str]] | None:
    """What the helper of :func:`_draw_beside_a_helper` sent, once it has ended; None if it
    ended without a whole answer."""
    import os
    import pickle
    import signal

    with os.fdopen(read_end, "rb") as fh:
        data = fh.read()  # to the end: the helper has drawn, or died
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # before the wait: then its pid is free
    try:
        _, status = os.waitpid(pid, 0)
    except ChildProcessError:
        status = 1
    if status != 0 or not data:
        return None
    try:
        images, failed = pickle.loads(data)
    except Exception:  # a truncated answer
        return None
    return dict(images), list(failed)


def _stop_with(pid: int) -> None:
    """SIGTERM in the drawing process while its helper ``pid`` draws: the helper is killed,
    then this process ends as SIGTERM ends it."""
    import os
    import signal

    with contextlib.suppress(OSError):
        os.kill(pid, signal.SIGKILL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGTERM)


def commit_plan(folder: str | Path, summary: dict[str, Any], data_files: list[Path],
                result: PlanResult, drawing: PlotDrawing | None = None
                ) -> tuple[Path, list[str]]:
    """Commit a plan's data files, then draw its plots and commit them too.

    ``plan.json`` is written first vouching for ``data_files`` (``"plots": {"pending": ...}``),
    so a plot that fails, hangs or is killed never costs the waypoints or the controller
    programs; after the plots it is rewritten vouching for the data files and every plot that
    was written (``"plots": {"written": [...], "failed": [...]}``). Both writes are atomic.

    Args:
        folder: The plan folder (already locked by the caller).
        summary: The record (``result.summary()`` plus the caller's keys); ``files`` and
            ``plots`` are set in it as committed last.
        data_files: Files written before the commit (``waypoints.csv``, exported programs).
        result: The plan (for the plots).
        drawing: The plots already being drawn beside the data files (:class:`PlotDrawing`);
            None: drawn after the commit, here.

    Returns:
        The path of ``plan.json`` and one line per plot that was not written.
    """
    from rfsw_plan.files import OutputLock

    out = Path(folder)
    record = summary
    record["files"] = [_in_folder(out, p) for p in data_files]
    record["plots"] = {"pending": list(PLAN_PLOTS)}
    path = write_plan_json(out / "plan.json", record, vouches_for=data_files)
    lock = OutputLock.held(out)
    if lock is not None:  # committed: an interruption from here on keeps the data files
        lock.on_abort(None)
    plots, failed = write_plan_plots(out, result, drawing)
    record["files"] = [_in_folder(out, p) for p in [*data_files, *plots]]
    record["plots"] = {"written": [p.name for p in plots], "failed": failed}
    write_plan_json(path, record, vouches_for=[*data_files, *plots])
    return path, failed


def _in_folder(folder: Path, path: str | Path) -> str:
    """``path`` as ``plan.json`` lists it: relative to the plan folder (POSIX separators) when
    it lies inside, so the same plan has the same bytes wherever its folder is."""
    p = Path(path)
    try:
        return p.resolve().relative_to(folder.resolve()).as_posix()
    except ValueError:
        return str(p)


def write_plan_folder(folder: str | Path, result: PlanResult,
                      robot_file: str | Path | None = None) -> Path:
    """Write a verified plan as the CLI does: ``waypoints.csv``, ``plan.json``, the plots.

    The folder is checked and locked first; an earlier run's outputs are marked stale;
    ``plan.json`` (with the SHA-256 of every file beside it) commits the data file before the
    plots are drawn and is rewritten to vouch for them after (:func:`commit_plan`), so a reader
    can tell a whole plan from a partial one (:meth:`~rfsw_plan.planfiles.folder.PlanFolder.open`).
    A plot that fails is logged as a warning and listed in ``plan.json`` (``plots.failed``);
    it is not raised.

    Args:
        folder: Output folder (created if needed).
        result: A plan from :func:`rfsw_plan.planning.api.plan`.
        robot_file: The robot description file the plan used (recorded as ``robot_file``).

    Returns:
        The path of ``plan.json``.

    Raises:
        OutputPathError: The folder cannot be written or another writer holds it.
    """
    from rfsw_plan.files import OutputLock, prepare_output_dir

    out = prepare_output_dir(folder, "folder")
    with OutputLock(out, "folder"):
        mark_outputs_stale(out, result.problem_name, PLAN_OUTPUTS)
        drawing = PlotDrawing(out, result)  # beside the data files, on another core
        try:
            summary = result.summary()
            if robot_file is not None:
                summary["robot_file"] = str(robot_file)
            path, failed = commit_plan(out, summary, write_plan_data(out, result), result,
                                       drawing)
        finally:
            drawing.close()
    for line in failed:
        log.warning("%s: %s", out, line)
    return path


def discard_incomplete_record(folder: str | Path) -> None:
    """Remove the ``incomplete`` record :func:`mark_outputs_stale` left in ``folder`` (an
    interrupted run into a folder it created leaves nothing behind)."""
    (Path(folder) / "plan.json").unlink(missing_ok=True)


def mark_outputs_stale(folder: str | Path, problem: str, outputs: tuple[str, ...]) -> None:
    """Before planning into ``folder``: ``plan.json`` becomes an ``incomplete`` record (first,
    so an earlier success record never sits beside removed or new data), then the other
    outputs of an earlier run are removed, with whatever a killed run left (hidden
    temporaries, a controller-program staging folder ``.export-*`` of earlier versions). If
    this run is killed, the folder says so.

    If the caller holds the folder's :class:`~rfsw_plan.files.OutputLock`, an interruption
    (Ctrl-C, SIGTERM) or an error before :func:`commit_plan` removes the data files this run
    wrote, so the folder holds the ``incomplete`` record alone, never a complete-looking
    ``waypoints.csv`` or program that nothing vouches for.

    Raises:
        OutputPathError: One of the output names is taken by a folder (one line, exit 2).
    """
    import shutil

    from rfsw_plan.exceptions import OutputPathError
    from rfsw_plan.files import OutputLock

    folder = Path(folder)
    for name in outputs:
        if (folder / name).is_dir():
            raise OutputPathError("-o", folder / name, "is a folder where rfsw-plan writes "
                                  "its file; move it away or choose another output folder")
    PlanRecord.incomplete(problem).write(folder / "plan.json")
    for name in outputs:
        if name != "plan.json":
            (folder / name).unlink(missing_ok=True)
        for tmp in folder.glob(f".{name}.*.tmp*"):  # left by a killed (SIGKILL) writer
            tmp.unlink(missing_ok=True)
    for stage in folder.glob(".export-*"):  # a killed export's staging folder
        if stage.is_dir():
            shutil.rmtree(stage, ignore_errors=True)
    lock = OutputLock.held(folder)
    if lock is not None:
        before = {p.name for p in folder.iterdir()}
        lock.on_abort(lambda: _remove_uncommitted(folder, problem, outputs, before))


def _remove_uncommitted(folder: Path, problem: str, outputs: tuple[str, ...],
                        before: set[str]) -> None:
    """Remove the data files a run wrote into ``folder`` before it was interrupted: its plan
    outputs (not the ``incomplete`` plan.json) and new controller programs of the problem."""
    stem = f"rfsw_{problem}".lower()
    for p in folder.iterdir():
        mine = p.name in outputs or (p.name not in before and p.name.lower().startswith(stem))
        if mine and p.name != "plan.json" and p.is_file():
            p.unlink(missing_ok=True)


def plot_lateral_error(path: str | Path, result: PlanResult) -> Path:
    """``lateral_error.png``: can the plan be trusted, at a glance (1500 x 650 px).

    The title gives the nominal and worst-case error of the plan, the window and the force
    uncertainty it tolerates. A narrow left panel shows the stationary start (plunge and dwell
    at s = 0) against time; the main panel the weld against arc length. Both show the window
    band, the plan's worst case under the force uncertainty (weld waypoints, verified
    numerically: e +- r), the three strategies at the waypoints and the written samples of
    ``waypoints.csv`` (the start panel on the samples' clock). The legend sits below the
    panels, outside the data.
    """
    from matplotlib.figure import Figure  # the object API; Agg draws it when saved

    task = result.task
    m = task.n_start
    s = task.s * 1e3
    t = task.time
    w = result.window
    u = result.options.force_uncertainty
    r = result.verification.prediction.worst
    sv = result.samples
    tr = result.trajectory
    fig = Figure(figsize=(15, 6.5), dpi=100)
    if m:
        gs = fig.add_gridspec(1, 2, width_ratios=(1, 3.2), wspace=0.04)
        a0 = fig.add_subplot(gs[0])
        a1 = fig.add_subplot(gs[1], sharey=a0)
        a1.tick_params(labelleft=False)
        axes = [a0, a1]
    else:
        a0 = None
        a1 = fig.add_subplot(1, 1, 1)
        axes = [a1]
    for ax in axes:
        ax.axhspan(w.lower * 1e3, w.upper * 1e3, color="tab:green", alpha=0.15,
                   label=f"weld window [{w.lower * 1e3:g}, {w.upper * 1e3:+g}] mm")
        ax.grid(True, alpha=0.3)
    e = result.e_lat
    start = np.zeros(0, bool)
    if sv is not None:
        start = sv.contact & np.isin(tr.phase, ("plunge", "dwell"))
        # The written samples run on the trajectory's clock (approach first, the dwell as
        # lengthened for the joint limits): the waypoints where the samples pass them.
        if start.any():
            t = result.waypoint_times()
    if u > 0:
        a1.fill_between(s[m:], (e[m:] - r[m:]) * 1e3, (e[m:] + r[m:]) * 1e3, color="tab:blue",
                        alpha=0.15, lw=0,
                        label=f"planned, worst case under +-{u * 100:.3g} % force")
        if a0 is not None and sv is not None and start.any():
            es, rs = sv.e_lat[start], u * sv.worst_per_unit[start]
            a0.fill_between(tr.t[start], (es - rs) * 1e3, (es + rs) * 1e3, color="tab:blue",
                            alpha=0.15, lw=0)
        elif a0 is not None:
            a0.fill_between(t[:m], (e[:m] - r[:m]) * 1e3, (e[:m] + r[:m]) * 1e3,
                            color="tab:blue", alpha=0.15, lw=0)
    none_max = float(np.max(np.abs(result.e_none))) * 1e3
    for ek, lab, c in ((result.e_none, f"no compensation (max |e| {none_max:.2f} mm, may run "
                        "off the axis)", "tab:red"),
                       (result.e_mirror, "mirror fake targets", "tab:orange"),
                       (e, "planned (NLP), waypoints", "tab:blue")):
        a1.plot(s[m:], ek[m:] * 1e3, color=c, label=lab)
        if a0 is not None:
            a0.plot(t[:m], ek[:m] * 1e3, "o-", color=c, ms=3, lw=1)
    if sv is not None:  # what waypoints.csv contains, verified sample by sample
        contact = sv.contact
        weld = contact & ~start
        a1.plot(tr.s[weld] * 1e3, sv.e_lat[weld] * 1e3, ".", color="k", ms=1.5,
                label=f"written samples in the material ({int(contact.sum())}, waypoints.csv)")
        if a0 is not None:
            a0.plot(tr.t[start], sv.e_lat[start] * 1e3, ".", color="k", ms=1.5)
    _clip_to_window(axes, result, u)
    if a0 is not None:
        a0.set_xlabel("time t [s] (clock of waypoints.csv)")
        a0.set_title("plunge and dwell (at s = 0)", fontsize=10)
        a0.set_ylabel("predicted lateral pin error [mm] (+ advancing side)")
        a1.set_title("weld", fontsize=10)
    else:
        a1.set_ylabel("predicted lateral pin error [mm] (+ advancing side)")
    a1.set_xlabel("arc length s [mm]")
    fig.suptitle(_lateral_title(result), fontsize=11)
    handles, labels = a1.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=9, frameon=False)
    fig.subplots_adjust(left=0.06, right=0.99, bottom=0.2, top=0.86)
    p = Path(path)
    write_figure(p, fig, dpi=100)
    return p


def _clip_to_window(axes: list[Any], result: PlanResult, u: float) -> None:
    """Scale the error axis to the window and the plan's worst case (15 % padding), so an
    uncompensated error of several mm does not squash the window; a curve beyond the axis is
    marked with an arrow at the edge and its extreme value."""
    w = result.window
    e = result.e_lat
    r = result.verification.prediction.worst
    sv = result.samples
    lo = min(w.lower, float(np.min(e - r)), float(np.min(result.e_mirror)))
    hi = max(w.upper, float(np.max(e + r)), float(np.max(result.e_mirror)))
    if sv is not None and sv.contact.any() and u > 0:
        c = sv.contact
        lo = min(lo, float(np.min(sv.e_lat[c] - u * sv.worst_per_unit[c])))
        hi = max(hi, float(np.max(sv.e_lat[c] + u * sv.worst_per_unit[c])))
    pad = 0.15 * (hi - lo)
    ylo, yhi = (lo - pad) * 1e3, (hi + pad) * 1e3
    for ax in axes:
        ax.set_ylim(ylo, yhi)
    en = result.e_none * 1e3
    for side, ext, off, va in (("above", float(np.max(en)), float(np.max(en)) > yhi, "top"),
                               ("below", float(np.min(en)), float(np.min(en)) < ylo, "bottom")):
        if off:
            axes[-1].annotate(f"no compensation {side} the axis (up to {ext:+.2f} mm)",
                              xy=(0.01, 0.97 if va == "top" else 0.03),
                              xycoords="axes fraction", ha="left", va=va, fontsize=9,
                              color="tab:red")


def _lateral_title(result: PlanResult) -> str:
    """Two title lines: the plan's nominal and worst-case error, the window, the tolerated
    force uncertainty (the numbers of the CLI's table, weld waypoints)."""
    w = result.window
    u = result.options.force_uncertainty
    nlp = next((b for b in result.baselines if b.name == "nlp"), None)
    line2 = f"window [{w.lower * 1e3:g}, {w.upper * 1e3:+g}] mm"
    if nlp is not None:
        line2 = f"planned: max |e| {nlp.max_abs_lateral * 1e3:.3f} mm nominal"
        if u > 0:
            line2 += f", {nlp.worst_case * 1e3:.3f} mm worst case under +-{u * 100:.3g} % force"
        line2 += f"; window [{w.lower * 1e3:g}, {w.upper * 1e3:+g}] mm"
    tol = result.tolerated_force_uncertainty
    if tol == np.inf:
        line2 += "; holds any force uncertainty"
    elif np.isfinite(tol):
        line2 += (f"; holds up to +-{100 * tol:.3g} % force uncertainty (requested "
                  f"+-{u * 100:.3g} %{'' if result.robust_held else ': NOT held'})")
    return f"{result.problem_name}: {result.verdict().line}\n{line2}"


#: Shading of the phases in :func:`plot_lateral_error_time`.
#: The weld is neutral grey: the window band is green and must stay visible while welding.
PHASE_COLOURS = {"approach": "0.92", "plunge": "tab:purple", "dwell": "tab:orange",
                 "accelerate": "tab:cyan", "weld": "0.6", "decelerate": "tab:cyan",
                 "stop": "tab:orange", "retract": "0.92"}


def plot_lateral_error_time(path: str | Path, result: PlanResult) -> Path:
    """``lateral_error_time.png``: the predicted lateral pin error and its margin to the window
    against time for every written sample (what ``waypoints.csv`` contains, verified sample
    by sample), with the phases shaded, the window band, the required margin and the worst
    case under the requested force uncertainty; 1400 x 800 px, legend outside the data."""
    from matplotlib.figure import Figure  # the object API; Agg draws it when saved

    tr = result.trajectory
    sv = result.samples
    w = result.window
    u = result.options.force_uncertainty
    if sv is None:
        raise ValueError("plot_lateral_error_time needs a sample-verified plan")
    c = sv.contact
    t = tr.t
    e = np.where(c, sv.e_lat, np.nan) * 1e3
    marg = np.where(c, sv.margin, np.nan) * 1e3
    r = np.where(c, u * sv.worst_per_unit, np.nan) * 1e3
    fig = Figure(figsize=(14, 8), dpi=100)
    a1, a2 = fig.subplots(2, 1, sharex=True)
    for ax in (a1, a2):
        start = 0
        ph = tr.phase
        for i in range(1, len(ph) + 1):
            if i == len(ph) or ph[i] != ph[start]:
                ax.axvspan(t[start], t[i - 1], color=PHASE_COLOURS.get(str(ph[start]), "0.9"),
                           alpha=0.12, lw=0)
                if ax is a1 and t[i - 1] - t[start] > 0.04 * (t[-1] - t[0]):
                    ax.text(0.5 * (t[start] + t[i - 1]), 1.0, str(ph[start]), fontsize=8,
                            ha="center", va="bottom", transform=ax.get_xaxis_transform())
                start = i
        ax.grid(True, alpha=0.3)
    a1.axhspan(w.lower * 1e3, w.upper * 1e3, color="tab:green", alpha=0.15,
               label=f"weld window [{w.lower * 1e3:g}, {w.upper * 1e3:+g}] mm")
    for bound in (w.lower, w.upper):  # the bounds stay visible over every phase shading
        a1.axhline(bound * 1e3, color="tab:green", lw=1.2, ls="--")
    if u > 0:
        a1.fill_between(t, e - r, e + r, color="tab:blue", alpha=0.2, lw=0,
                        label=f"worst case under +-{100 * u:.3g} % force")
    a1.plot(t, e, color="tab:blue", lw=1, label="predicted lateral pin error (every sample)")
    a1.set_ylabel("lateral pin error [mm]\n(+ advancing side)")
    a2.plot(t, marg, color="k", lw=1, label="margin to the nearest window bound")
    # every written sample in the margin colours of plan.html (page3d.margin_colours), as
    # the numbers matplotlib reads from their hex texts (an empty list: no sample to colour)
    from rfsw_plan.planfiles.page3d import margin_rgba

    a2.scatter(t[c], marg[c], s=4, lw=0, zorder=3,
               c=margin_rgba(marg[c], 0.5 * (w.upper - w.lower) * 1e3) if c.any() else [],
               label="samples, coloured by margin (as in plan.html)")
    if u > 0:
        a2.plot(t, marg - r, color="tab:red", lw=0.8,
                label=f"margin of the worst case (+-{100 * u:.3g} % force)")
    a2.axhline(result.options.margin * 1e3, color="tab:red", ls="--", lw=0.8,
               label=f"required margin {result.options.margin * 1e3:g} mm")
    a2.axhline(0.0, color="k", lw=0.5)
    a2.set_ylabel("margin [mm] (negative = outside)")
    a2.set_xlabel("time t [s] (sample time of waypoints.csv)")
    tol = result.tolerated_force_uncertainty
    held = ("any force uncertainty" if tol == np.inf
            else f"force uncertainty up to +-{100 * tol:.3g} %")
    fig.suptitle(f"{result.problem_name}: {int(c.sum())} written in-material samples, all in "
                 f"the window; holds {held} (requested +-{100 * u:.3g} %)", fontsize=11)
    for ax in (a1, a2):
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0)
    tight_layout(fig, rect=(0, 0, 1, 0.97))
    p = Path(path)
    write_figure(p, fig, dpi=100)
    return p


def tight_layout(fig: Any, pad: float = 1.08, rect: tuple[float, ...] | None = None) -> None:
    """``fig.tight_layout(pad=pad, rect=rect)``: the same layout, computed the same way
    (matplotlib's ``TightLayoutEngine.execute``), without the placeholder layout engine
    ``Figure.tight_layout`` leaves on the figure. ``savefig`` draws a figure that has a layout
    engine once before it draws it into the image; without one it draws it once: the same
    pixels, one draw of the figure fewer."""
    from matplotlib.layout_engine import TightLayoutEngine

    # rect None as Figure.tight_layout passes it (not the engine's default, another layout)
    TightLayoutEngine(pad=pad, h_pad=None, w_pad=None, rect=rect).execute(fig)  # type: ignore[arg-type]
