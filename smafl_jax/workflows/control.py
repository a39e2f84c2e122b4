"""Closed-loop control simulation as one library call (the workflow behind ``smafl control``).

`run_control` loads the identified model (the I-I compensator's) and the plant
model, builds the reference ('sine', 'step', a CSV or an array), runs the PID /
composite PID loop (`smafl_jax.control._control`), checks the controller's drive against
the range the plant model was fitted on, and writes, atomically, to ``out``:
``trajectory.csv``, ``tracking.png``, ``error.png`` and ``metrics.json``.
`build_loop` (the loop and its settings, every option checked) is shared with
the sweep workflow (`smafl_jax.workflows.sweep`).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from .._errors import UserInputError

if TYPE_CHECKING:
    from ..control._control import ClosedLoop

PathLike = str | os.PathLike

__all__ = [
    "FILES",
    "ControlResult",
    "run_control",
    "build_loop",
    "load_reference",
    "check_option",
    "reference_check",
    "DEFAULT_MODEL",
    "DEFAULT_UMAX",
]

LOGGER = logging.getLogger(__name__)

#: The files `run_control` writes to its output folder.
FILES = ("trajectory.csv", "tracking.png", "error.png", "metrics.json")

#: The bundled true cascade, found beside the package (``<repo>/datasets/truth.json``), not relative to the working
#: folder, so the default works from any folder with a source checkout or an editable install (``pip install -e .``).
DEFAULT_MODEL = Path(__file__).resolve().parents[2] / "datasets" / "truth.json"

#: Lower limits of the loop options (also applied to swept values): strictly positive / non-negative.
POSITIVE_OPTIONS = ("dt", "duration", "umax", "tf")
NONNEGATIVE_OPTIONS = ("noise", "quantum", "K", "kp", "ki", "kd", "eval_start")

#: Most samples one closed-loop run may have (~1 GB of trajectory arrays at float64).
MAX_SAMPLES = 10_000_000

#: The drive limit when none is given (V): the paper's maximum test voltage.  Kept when the plant model was trained on
#: a narrower range (a note says so): the fitted range is what one record visited, not the actuator's limit, and a
#: default that moved with the model would change every loop's saturation without being asked; the drive range
#: warning reports any drive that does leave the trained range.
DEFAULT_UMAX = 7.4

CONTROLLERS = ("pid", "composite")

#: Columns of ``trajectory.csv``.
TRAJECTORY_COLUMNS = ("time_s", "reference", "y", "y_meas", "error", "u", "u1", "u2", "saturated")


def option_namer(option_names: Mapping[str, str] | None):
    """How error messages name setting ``name``: ``option_names[name]``, else the keyword itself."""
    names = dict(option_names or {})
    return lambda name: names.get(name, name)


class ControlResult(NamedTuple):
    """What `run_control` produced.

    ``metrics``: e_mean_mm (eq. 8), rmse_mm, max_abs_error_mm, saturated_fraction, u_min_V, u_max_V (floats);
    ``trajectory``: the time series of ``trajectory.csv`` and more (numpy arrays); ``settings``: the loop's
    settings as written to metrics.json (with ``reference_check``: the reference against the output the plant can
    reach, `reference_check`); ``range_checks``: the drive against the plant model's fitted raw and
    effective input ranges; ``warnings``: the reference and range warnings as text; ``out`` and ``files`` (by name).
    """

    metrics: dict[str, float]
    trajectory: dict[str, np.ndarray]
    settings: dict
    range_checks: list[dict]
    warnings: list[str]
    out: Path
    files: dict[str, Path]


def check_option(name: str, value: float, option_names: Mapping[str, str] | None = None) -> None:
    """`UserInputError` unless ``value`` is finite and within the limit of loop option ``name``."""
    flag = option_namer(option_names)(name)
    if name in POSITIVE_OPTIONS and not (np.isfinite(value) and value > 0):
        raise UserInputError(f"{flag} must be > 0, got {value}")
    if name in NONNEGATIVE_OPTIONS and not (np.isfinite(value) and value >= 0):
        raise UserInputError(f"{flag} must be >= 0, got {value}")


def _check_samples(span_s, dt, what, dt_name):
    n = span_s / dt + 1
    if not np.isfinite(n) or n > MAX_SAMPLES:
        raise UserInputError(
            f"{what} of {span_s:g} s at {dt_name} {dt:g} s is {n:.3g} samples, more than the limit of {MAX_SAMPLES:.0e}: "
            f"shorten it or use a larger {dt_name}"
        )


def _read_reference_csv(path):
    """(time, values, column name) from a reference CSV with a header; errors name the file and row (the line of
    the file, counted from 1 with the header)."""
    import csv

    try:
        with open(path, newline="") as f:
            reader = csv.reader(f)
            rows = [(reader.line_num, r) for r in reader if any(c.strip() for c in r)]
    except (UnicodeDecodeError, csv.Error) as exc:
        raise UserInputError(f"{path}: cannot read as CSV ({exc})") from None
    if not rows:
        raise UserInputError(f"{path}: the reference file is empty; need a header with 'time_s' and a reference column")
    header = [h.strip().lstrip("\ufeff") for h in rows[0][1]]
    if "time_s" not in header or len(header) < 2:
        raise UserInputError(f"{path}: need a 'time_s' column and a reference column, found {header}")
    col = next(h for h in header if h != "time_s")
    it, ic = header.index("time_s"), header.index(col)
    t, r = [], []
    for line, row in rows[1:]:
        try:
            t.append(float(row[it]))
            r.append(float(row[ic]))
        except (ValueError, IndexError):
            raise UserInputError(f"{path}, row {line}: expected numbers in 'time_s' and '{col}', got {row}") from None
        if not (np.isfinite(t[-1]) and np.isfinite(r[-1])):
            name = "time_s" if not np.isfinite(t[-1]) else col
            bad = sum(1 for _, x in rows[1:] if len(x) > max(it, ic) and not _finite(x[header.index(name)]))
            raise UserInputError(
                f"{path}, row {line}: '{name}' is {row[header.index(name)].strip()!r}"
                + (f" ({bad} such rows in all)" if bad > 1 else "")
                + "; a reference needs a finite value on every row (fill or drop those rows)"
            )
        if len(t) > 1 and t[-1] <= t[-2]:
            raise UserInputError(f"{path}, row {line}: time_s {t[-1]:g} does not increase (previous row {t[-2]:g})")
    return np.asarray(t), np.asarray(r), col


def _finite(cell) -> bool:
    try:
        return bool(np.isfinite(float(cell)))
    except ValueError:
        return False


def load_reference(spec, dt: float, duration: float, option_names: Mapping[str, str] | None = None) -> np.ndarray:
    """Reference samples (mm) on the ``dt`` grid from 'sine', 'step', a CSV file (time_s + one column, interpolated
    onto the grid) or an array of samples already on it."""
    from ..control._control import sine_reference, step_reference

    o = option_namer(option_names)
    if not isinstance(spec, (str, os.PathLike)):
        ref = np.asarray(spec, dtype=np.float64)
        if ref.ndim != 1 or not np.all(np.isfinite(ref)):
            raise UserInputError(f"{o('reference')}: an array reference must be 1-D and finite, got shape {ref.shape}")
        return ref
    if spec in ("sine", "step"):
        _check_samples(duration, dt, o("duration"), o("dt"))
        return sine_reference(duration, dt) if spec == "sine" else step_reference(duration, dt)
    path = Path(spec)
    if not path.exists():
        raise UserInputError(f"{o('reference')} {str(spec)!r}: not 'sine' or 'step' and no such file")
    if path.is_dir():
        raise UserInputError(f"{o('reference')} {str(spec)!r}: is a folder, expected a CSV file")
    t, r, col = _read_reference_csv(path)
    if len(t) < 2 or not np.all(np.isfinite(t)) or not np.all(np.isfinite(r)) or np.any(np.diff(t) <= 0):
        raise UserInputError(f"{path}: time_s must be finite and increasing and '{col}' finite, with at least 2 rows")
    _check_samples(t[-1] - t[0], dt, f"the reference in {path}", o("dt"))
    grid = t[0] + np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1) * dt
    return np.interp(grid, t, r)


def _default_model(o) -> str:
    """The bundled model's path; a clear error when the package was installed without the repository's datasets/."""
    if not DEFAULT_MODEL.is_file():
        raise UserInputError(
            f"no {o('model')} given and the bundled default {DEFAULT_MODEL} is missing (an install without the repository's "
            f"datasets/ folder): pass {o('model')} MODEL.json or a fit.json"
        )
    return str(DEFAULT_MODEL)


def _load_model(source) -> tuple[Any, dict, str]:
    """``(model, fit.json / model-file document, label)`` from a path or a model object."""
    from .._io import load_model_file

    if isinstance(source, (str, os.PathLike)):
        model, doc = load_model_file(source)
        return model, doc, str(source)
    return source, {}, f"<{type(source).__name__} object>"


def build_loop(
    model: PathLike | Any | None = None,
    *,
    plant: PathLike | Any | None = None,
    reference: PathLike | np.ndarray = "sine",
    controller: str = "composite",
    kp: float = 35.0,
    ki: float = 20.0,
    kd: float = 0.0,
    tf: float = 0.05,
    K: float = 10.0,
    dt: float = 0.01,
    duration: float = 40.0,
    umax: float | None = None,
    noise: float = 0.0,
    quantum: float = 0.0,
    eval_start: float = 0.0,
    compensator_cascade: bool = False,
    seed: int = 0,
    option_names: Mapping[str, str] | None = None,
) -> tuple[ClosedLoop, dict]:
    """The `ClosedLoop` and its settings (as metrics.json records them); every option is checked first.

    ``model``: the identified model the I-I compensator uses (a model file or fit.json path, or a model
    object; default the bundled ``datasets/truth.json``).  ``plant``: the model simulated as the plant
    (default ``model`` itself, i.e. no mismatch).  ``reference``: ``"sine"`` (paper: sin(3 pi/10 t + pi/2)
    + 1.5 mm over ``duration``), ``"step"`` (2.5 mm), a CSV with ``time_s`` and a reference column, or an
    array of samples on the ``dt`` grid.  ``controller``: ``"pid"`` or ``"composite"`` (PID + I-I
    compensator of gain ``K``, on the static hysteresis model unless ``compensator_cascade``).  The drive
    is limited to [0, ``umax``] V (default `DEFAULT_UMAX`, with a note when it lies above the plant model's trained
    input range); ``noise`` / ``quantum``: sensor noise sd and quantisation step (mm);
    metrics count samples from ``eval_start`` s on.  ``option_names``: how error messages name the settings.
    """
    import jax
    import jax.numpy as jnp

    from ..control._control import PID, ClosedLoop, IICompensator

    o = option_namer(option_names)
    umax_given = umax is not None
    umax = DEFAULT_UMAX if umax is None else umax
    values = {"dt": dt, "duration": duration, "umax": umax, "tf": tf, "noise": noise, "quantum": quantum, "K": K}
    values |= {"kp": kp, "ki": ki, "kd": kd, "eval_start": eval_start}
    for name in POSITIVE_OPTIONS + NONNEGATIVE_OPTIONS:
        check_option(name, values[name], option_names)
    if controller not in CONTROLLERS:
        raise UserInputError(f"{o('controller')} must be one of {CONTROLLERS}, got {controller!r}")
    if model is None:
        model = _default_model(o)
    ident, ident_doc, model_label = _load_model(model)
    plant_model, plant_doc, plant_label = _load_model(plant) if plant is not None else (ident, ident_doc, model_label)
    ref = load_reference(reference, dt, duration, option_names)
    if len(ref) < 2:
        raise UserInputError(f"the reference has fewer than 2 samples: increase {o('duration')} or decrease {o('dt')}")
    if not umax_given:
        _default_umax_note(umax, plant_doc, o)
    try:
        comp = IICompensator(ident, K, hysteresis_only=not compensator_cascade) if controller == "composite" else None
        loop = ClosedLoop(
            plant=plant_model,
            pid=PID(kp, ki, kd, tf=tf, umin=0.0, umax=umax),
            reference=jnp.asarray(ref),
            compensator=comp,
            noise_sd=jnp.asarray(noise),
            quantum=jnp.asarray(quantum),
            eval_start=jnp.asarray(eval_start),
            key=jax.random.PRNGKey(seed),
        )
    except TypeError as exc:
        raise UserInputError(str(exc)) from None
    settings = {
        "model": model_label,
        "plant": plant_label,
        "reference": reference if isinstance(reference, (str, os.PathLike)) else f"array of {len(ref)} samples",
        "controller": controller,
        "kp": kp,
        "ki": ki,
        "kd": kd,
        "tf_s": tf,
        "K": K if controller == "composite" else None,
        "compensator_forward_model": ("cascade" if compensator_cascade else f"static {type(ident.hysteresis).__name__}")
        if controller == "composite"
        else None,
        "dt_s": dt,
        "n_samples": int(len(ref)),
        "u_range_V": [0.0, umax],
        "noise_sd_mm": noise,
        "quantum_mm": quantum,
        "eval_start_s": eval_start,
        "seed": seed,
        "anti_windup": "conditional integration",
        "plant_initial_state": "at rest at 0 V",
        # the ranges the plant model was fitted on: a drive outside them runs the model where no data was
        "plant_fitted_ranges": {k: (plant_doc.get("data") or {}).get(k) for k in ("input_range", "effective_input_range")},
    }
    return loop, settings


def _default_umax_note(umax, plant_doc, o):
    """Say which drive limit is used when none was given and it lies above the plant model's trained input range."""
    from ..models._range import range_tolerance

    rng = (plant_doc.get("data") or {}).get("input_range")
    if not (isinstance(rng, (list, tuple)) and len(rng) == 2):
        return
    lo, hi = float(rng[0]), float(rng[1])
    if umax > hi + range_tolerance(lo, hi):
        LOGGER.info(
            f"note: no {o('umax')} given: the drive is limited to {umax:g} V (the paper's maximum test voltage), above the "
            f"input range [{lo:.4g}, {hi:.4g}] V the plant model was trained on; a drive above {hi:.4g} V runs the model "
            f"where it has no data (pass {o('umax')} {hi:.4g} to stay inside it)"
        )


def reference_check(plant, ref, umax: float, reference_name: str) -> tuple[dict, str | None]:
    """The reference against the output the plant model can reach with its drive in [0, ``umax``] V, and a warning.

    The reachable range is `smafl_jax.control.reachable_output` (a slow full cycle of the drive); reference samples
    beyond it by more than 1 % of its span (`models._range.range_tolerance`) cannot be tracked: the drive saturates
    there and the loop's error measures the plant's limits rather than the controller.  Seen in a new-user trial:
    references of -1 mm and 8 mm on a plant reaching 0.6-5.1 mm ran with no word beyond "saturated 100 %"."""
    from ..control._control import reachable_output
    from ..models._range import range_tolerance

    try:
        lo, hi = reachable_output(plant, umax)
    except (TypeError, ValueError):  # a plant the reach cannot be computed for: nothing to say
        return {"checked": False}, None
    ref = np.asarray(ref, dtype=np.float64)
    tol = range_tolerance(lo, hi)
    above, below = ref > hi + tol, ref < lo - tol
    doc = {
        "checked": True,
        "reachable_output_mm": [lo, hi],
        "drive_range_V": [0.0, float(umax)],
        "reference_range_mm": [float(ref.min()), float(ref.max())],
        "tolerance_mm": tol,
        "n_samples": int(ref.size),
        "n_above": int(above.sum()),
        "n_below": int(below.sum()),
    }
    n_out = doc["n_above"] + doc["n_below"]
    if not n_out:
        return doc, None
    by = max(float(np.max(ref - hi)), float(np.max(lo - ref)))
    doc["warning"] = (
        f"reference {reference_name} spans [{ref.min():.4g}, {ref.max():.4g}] mm, but the plant model's output reaches only "
        f"[{lo:.4g}, {hi:.4g}] mm with the drive in [0, {umax:g}] V (over a slow full cycle of the drive): {n_out} of "
        f"{ref.size} reference samples ({100 * n_out / ref.size:.1f} %) are out of reach ({doc['n_above']} above, "
        f"{doc['n_below']} below, by up to {by:.3g} mm); the loop cannot track them, the drive saturates there and the "
        "error there measures the plant's limits, not the controller"
    )
    return doc, doc["warning"]


def drive_range_checks(plant, settings: dict, u, dt: float) -> tuple[list[dict], list[str]]:
    """Range checks of the controller's drive ``u`` against the plant model's fitted ranges, and their warnings.

    Warnings are logged (WARNING), notes (a model without a fitted range) logged at INFO.
    """
    from ..models._range import model_range_checks

    fitted = settings.get("plant_fitted_ranges") or {}
    checks = model_range_checks(plant, fitted, np.asarray(u), dt, "drive u")
    warnings = []
    for chk in checks:
        if chk.get("warning"):
            warnings.append(f"plant model: {chk['warning']}")
            LOGGER.warning(warnings[-1])
        elif chk.get("note"):
            LOGGER.info(f"note: plant model: {chk['note']}")
    return checks, warnings


def prepare_out(out: PathLike, logger: logging.Logger = LOGGER) -> Path:
    """Create (and probe) the output folder; a note (logged) when it holds results whose files will be replaced."""
    from .._io import prepare_out_dir

    out = prepare_out_dir(out, announce=False)
    existing = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    if existing:
        shown = ", ".join(existing[:6]) + (" ..." if len(existing) > 6 else "")
        logger.info(f"note: {out} already holds results ({shown}); files of the same name will be replaced")
    return out


def _figures(traj: dict, metrics: dict, controller: str, reference_name: str):
    """(tracking, error) figures; `Figure` objects, not pyplot: nothing global changes and nothing stays open."""
    from matplotlib.figure import Figure

    t = traj["time_s"]
    fig = Figure(figsize=(8, 6))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(t, traj["reference"], "k--", label="reference")
    ax1.plot(t, traj["y"], label=f"output ({controller})")
    ax1.set_ylabel("displacement (mm)")
    ax1.legend()
    ax2.plot(t, traj["u"], label="drive u")
    if controller == "composite":
        ax2.plot(t, traj["u2"], label="I-I part u2", alpha=0.7)
    ax2.set_ylabel("voltage (V)")
    ax2.set_xlabel("time (s)")
    ax2.legend()
    fig.suptitle(f"{controller}, reference {reference_name}: e_mean = {metrics['e_mean_mm']:.4g} mm")
    err = Figure(figsize=(8, 3))
    ax = err.subplots()
    ax.plot(t, traj["error"])
    ax.set_xlabel("time (s)")
    ax.set_ylabel("tracking error y_d - y (mm)")
    return fig, err


def run_control(
    model: PathLike | Any | None = None,
    *,
    out: PathLike,
    plant: PathLike | Any | None = None,
    reference: PathLike | np.ndarray = "sine",
    controller: str = "composite",
    kp: float = 35.0,
    ki: float = 20.0,
    kd: float = 0.0,
    tf: float = 0.05,
    K: float = 10.0,
    dt: float = 0.01,
    duration: float = 40.0,
    umax: float | None = None,
    noise: float = 0.0,
    quantum: float = 0.0,
    eval_start: float = 0.0,
    compensator_cascade: bool = False,
    seed: int = 0,
    option_names: Mapping[str, str] | None = None,
) -> ControlResult:
    """Simulate the closed loop (PID or composite PID) on ``plant`` and write trajectory, figures and metrics to ``out``.

    The settings are those of `build_loop` (checked before anything is written).  A drive outside the
    range the plant model was fitted on is reported in ``range_checks`` / ``warnings`` (and logged), a reference
    outside the output the plant can reach in ``warnings`` and ``settings["reference_check"]`` (`reference_check`); an
    unstable loop (non-finite metrics) is a `UserInputError`.  An ``out`` folder holding earlier results
    is reused: files of the same name are replaced (logged as a note), others are left alone.
    """
    from .._io import atomic_savefig, atomic_write_csv, atomic_write_json
    from ..control._control import simulate_closed_loop

    loop, settings = build_loop(
        model,
        plant=plant,
        reference=reference,
        controller=controller,
        kp=kp,
        ki=ki,
        kd=kd,
        tf=tf,
        K=K,
        dt=dt,
        duration=duration,
        umax=umax,
        noise=noise,
        quantum=quantum,
        eval_start=eval_start,
        compensator_cascade=compensator_cascade,
        seed=seed,
        option_names=option_names,
    )
    out = prepare_out(out)
    ref_name = Path(str(settings["reference"])).name if isinstance(reference, (str, os.PathLike)) else "(array)"
    ref_check, ref_warning = reference_check(loop.plant, loop.reference, settings["u_range_V"][1], ref_name)
    settings["reference_check"] = ref_check  # beside the plant's fitted ranges: what the loop can be asked to do
    if ref_warning:
        LOGGER.warning(ref_warning)
    LOGGER.info(f"simulating {settings['n_samples']} samples ({controller}) ...")
    metrics, traj = simulate_closed_loop(loop, dt)
    metrics = {k: float(v) for k, v in metrics.items()}
    traj = {k: np.asarray(v, dtype=np.float64) for k, v in traj.items()}
    if not all(np.isfinite(v) for v in metrics.values()):
        raise UserInputError("the closed loop produced non-finite values (unstable gains for this sample time?)")
    range_checks, warnings = drive_range_checks(loop.plant, settings, traj["u"], dt)
    warnings = ([ref_warning] if ref_warning else []) + warnings
    # figures first: nothing is written when drawing fails
    tracking, error = _figures(traj, metrics, controller, Path(str(settings["reference"])).name)
    files = {name: out / name for name in FILES}
    atomic_write_csv(files["trajectory.csv"], {k: traj[k] for k in TRAJECTORY_COLUMNS})
    atomic_savefig(tracking, files["tracking.png"])
    atomic_savefig(error, files["error.png"])
    atomic_write_json(files["metrics.json"], {**metrics, "settings": settings, "range_checks": range_checks})
    return ControlResult(metrics, traj, settings, range_checks, warnings, out, files)
