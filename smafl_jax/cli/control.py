"""``smafl control``: closed-loop PID / composite PID simulation of a saved model (paper section 4)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from .._errors import UserInputError

#: The bundled true cascade, found beside the package (``<repo>/datasets/truth.json``), not relative to the working
#: folder, so the default works from any folder with a source checkout or an editable install (``pip install -e .``).
DEFAULT_MODEL = Path(__file__).resolve().parents[2] / "datasets" / "truth.json"


def _default_model() -> str:
    """The bundled model's path; a clear error when the package was installed without the repository's datasets/."""
    if not DEFAULT_MODEL.is_file():
        raise UserInputError(
            f"no --model given and the bundled default {DEFAULT_MODEL} is missing (an install without the repository's "
            "datasets/ folder): pass --model MODEL.json or a fit.json"
        )
    return str(DEFAULT_MODEL)


def add_loop_arguments(p):
    """Options shared by `smafl control` and `smafl sweep`."""
    p.add_argument(
        "--model",
        default=None,
        help="identified model used by the I-I compensator (model file or fit.json; default: the bundled "
        "datasets/truth.json of this installation, found from any working folder)",
    )
    p.add_argument("--plant", default=None, help="model simulated as the plant (default: the --model itself, i.e. no mismatch)")
    p.add_argument(
        "--reference",
        default="sine",
        help="'sine' (paper: sin(3*pi/10 t + pi/2) + 1.5 mm), 'step' (2.5 mm) or a CSV with time_s and a reference column (mm)",
    )
    p.add_argument(
        "--controller", choices=("pid", "composite"), default="composite", help="PID alone or PID + integral-inverse compensator"
    )
    p.add_argument("--kp", type=float, default=35.0, help="proportional gain, V/mm (paper: 35)")
    p.add_argument("--ki", type=float, default=20.0, help="integral gain, V/(mm s) (paper: 20)")
    p.add_argument("--kd", type=float, default=0.0, help="derivative gain, V s/mm (paper: 0)")
    p.add_argument("--tf", type=float, default=0.05, help="derivative filter time constant, s")
    p.add_argument("--K", type=float, default=10.0, help="I-I compensator gain, V/(mm s) (paper: 10)")
    p.add_argument("--dt", type=float, default=0.01, help="controller sample time, s (not given in the paper; default 0.01)")
    p.add_argument("--duration", type=float, default=40.0, help="simulated time for sine/step references, s")
    p.add_argument("--umax", type=float, default=7.4, help="upper drive limit, V (paper's maximum test voltage); lower limit 0 V")
    p.add_argument("--noise", type=float, default=0.0, help="measurement noise standard deviation, mm")
    p.add_argument(
        "--quantum", type=float, default=0.0, help="sensor quantisation step, mm (0 = none; 16 bit over 10 mm = 1.5e-4)"
    )
    p.add_argument(
        "--eval-start", type=float, default=0.0, help="metrics count samples from this time on, s (0 = whole record, eq. 8)"
    )
    p.add_argument(
        "--compensator-cascade",
        action="store_true",
        help="run the I-I loop on the whole identified cascade instead of its static hysteresis model",
    )
    p.add_argument("--seed", type=int, default=0, help="noise seed")


#: Lower limits of the loop options (also applied to swept values): strictly positive / non-negative.
POSITIVE_OPTIONS = ("dt", "duration", "umax", "tf")
NONNEGATIVE_OPTIONS = ("noise", "quantum", "K", "kp", "ki", "kd", "eval_start")

#: Most samples one closed-loop run may have (~1 GB of trajectory arrays at float64).
MAX_SAMPLES = 10_000_000


def check_option(name, value):
    """`UserInputError` unless ``value`` is finite and within the limit of loop option ``name``."""
    flag = "--" + name.replace("_", "-")
    if name in POSITIVE_OPTIONS and not (np.isfinite(value) and value > 0):
        raise UserInputError(f"{flag} must be > 0, got {value}")
    if name in NONNEGATIVE_OPTIONS and not (np.isfinite(value) and value >= 0):
        raise UserInputError(f"{flag} must be >= 0, got {value}")


def _check_samples(span_s, dt, what):
    n = span_s / dt + 1
    if not np.isfinite(n) or n > MAX_SAMPLES:
        raise UserInputError(
            f"{what} of {span_s:g} s at --dt {dt:g} s is {n:.3g} samples, more than the limit of {MAX_SAMPLES:.0e}: "
            "shorten it or use a larger --dt"
        )


def _read_reference_csv(path):
    """(time, values, column name) from a reference CSV with a header; errors name the file and line."""
    import csv

    try:
        with open(path, newline="") as f:
            rows = [r for r in csv.reader(f) if any(c.strip() for c in r)]
    except (UnicodeDecodeError, csv.Error) as exc:
        raise UserInputError(f"{path}: cannot read as CSV ({exc})") from None
    if not rows:
        raise UserInputError(f"{path}: the reference file is empty; need a header with 'time_s' and a reference column")
    header = [h.strip().lstrip("\ufeff") for h in rows[0]]
    if "time_s" not in header or len(header) < 2:
        raise UserInputError(f"{path}: need a 'time_s' column and a reference column, found {header}")
    col = next(h for h in header if h != "time_s")
    it, ic = header.index("time_s"), header.index(col)
    t, r = [], []
    for line, row in enumerate(rows[1:], start=2):
        try:
            t.append(float(row[it]))
            r.append(float(row[ic]))
        except (ValueError, IndexError):
            raise UserInputError(f"{path}, row {line}: expected numbers in 'time_s' and '{col}', got {row}") from None
    return np.asarray(t), np.asarray(r), col


def load_reference(spec, dt, duration):
    """Reference samples on the ``dt`` grid from 'sine', 'step' or a CSV file."""
    from .._control import sine_reference, step_reference

    if spec in ("sine", "step"):
        _check_samples(duration, dt, "--duration")
        return sine_reference(duration, dt) if spec == "sine" else step_reference(duration, dt)
    path = Path(spec)
    if not path.exists():
        raise UserInputError(f"--reference {spec!r}: not 'sine' or 'step' and no such file")
    if path.is_dir():
        raise UserInputError(f"--reference {spec!r}: is a folder, expected a CSV file")
    t, r, col = _read_reference_csv(path)
    if len(t) < 2 or not np.all(np.isfinite(t)) or not np.all(np.isfinite(r)) or np.any(np.diff(t) <= 0):
        raise UserInputError(f"{path}: time_s must be finite and increasing and '{col}' finite, with at least 2 rows")
    _check_samples(t[-1] - t[0], dt, f"the reference in {path}")
    grid = t[0] + np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1) * dt
    return np.interp(grid, t, r)


def build_loop(args):
    """(ClosedLoop, settings dict) from the parsed options."""
    import jax
    import jax.numpy as jnp

    from .. import load_model_file
    from .._control import PID, ClosedLoop, IICompensator

    for name in POSITIVE_OPTIONS + NONNEGATIVE_OPTIONS:
        check_option(name, getattr(args, name))
    if args.model is None:
        args.model = _default_model()
    model, model_doc = load_model_file(args.model)
    plant, plant_doc = load_model_file(args.plant) if args.plant else (model, model_doc)
    ref = load_reference(args.reference, args.dt, args.duration)
    if len(ref) < 2:
        raise UserInputError("the reference has fewer than 2 samples: increase --duration or decrease --dt")
    try:
        comp = (
            IICompensator(model, args.K, hysteresis_only=not args.compensator_cascade) if args.controller == "composite" else None
        )
        loop = ClosedLoop(
            plant=plant,
            pid=PID(args.kp, args.ki, args.kd, tf=args.tf, umin=0.0, umax=args.umax),
            reference=jnp.asarray(ref),
            compensator=comp,
            noise_sd=jnp.asarray(args.noise),
            quantum=jnp.asarray(args.quantum),
            eval_start=jnp.asarray(args.eval_start),
            key=jax.random.PRNGKey(args.seed),
        )
    except TypeError as exc:
        raise UserInputError(str(exc)) from None
    settings = {
        "model": str(args.model),
        "plant": str(args.plant or args.model),
        "reference": args.reference,
        "controller": args.controller,
        "kp": args.kp,
        "ki": args.ki,
        "kd": args.kd,
        "tf_s": args.tf,
        "K": args.K if args.controller == "composite" else None,
        "compensator_forward_model": ("cascade" if args.compensator_cascade else f"static {type(model.hysteresis).__name__}")
        if args.controller == "composite"
        else None,
        "dt_s": args.dt,
        "n_samples": int(len(ref)),
        "u_range_V": [0.0, args.umax],
        "noise_sd_mm": args.noise,
        "quantum_mm": args.quantum,
        "eval_start_s": args.eval_start,
        "seed": args.seed,
        "anti_windup": "conditional integration",
        "plant_initial_state": "at rest at 0 V",
        # the ranges the plant model was fitted on: a drive outside them runs the model where no data was
        "plant_fitted_ranges": {k: (plant_doc.get("data") or {}).get(k) for k in ("input_range", "effective_input_range")},
    }
    return loop, settings


def drive_range_checks(plant, settings, u, dt):
    """Range checks of the controller's drive ``u`` against the plant model's fit, warnings printed to stderr."""
    from .._range import model_range_checks

    fitted = settings.get("plant_fitted_ranges") or {}
    checks = model_range_checks(plant, fitted, np.asarray(u), dt, "drive u")
    for chk in checks:
        if chk.get("warning"):
            print(f"warning: plant model: {chk['warning']}", file=sys.stderr)
        elif chk.get("note"):
            print(f"note: plant model: {chk['note']}", file=sys.stderr)
    return checks


def add_parser(sub):
    p = sub.add_parser("control", help="closed-loop PID / composite PID (PID + I-I compensator) simulation")
    add_loop_arguments(p)
    p.add_argument("--out", required=True, help="output folder (tracking.png, error.png, trajectory.csv, metrics.json)")
    p.set_defaults(func=run)
    return p


def run(args):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .._control import simulate_closed_loop
    from .._io import atomic_savefig, atomic_write_csv, atomic_write_json, prepare_out_dir

    loop, settings = build_loop(args)
    out = prepare_out_dir(args.out)
    print(f"simulating {settings['n_samples']} samples ({args.controller}) ...", file=sys.stderr)
    metrics, traj = simulate_closed_loop(loop, args.dt)
    metrics = {k: float(v) for k, v in metrics.items()}
    traj = {k: np.asarray(v, dtype=np.float64) for k, v in traj.items()}
    if not all(np.isfinite(v) for v in metrics.values()):
        raise UserInputError("the closed loop produced non-finite values (unstable gains for this sample time?)")
    t = traj["time_s"]
    range_checks = drive_range_checks(loop.plant, settings, traj["u"], args.dt)
    atomic_write_csv(
        out / "trajectory.csv",
        {k: traj[k] for k in ("time_s", "reference", "y", "y_meas", "error", "u", "u1", "u2", "saturated")},
    )
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax1.plot(t, traj["reference"], "k--", label="reference")
    ax1.plot(t, traj["y"], label=f"output ({args.controller})")
    ax1.set_ylabel("displacement (mm)")
    ax1.legend()
    ax2.plot(t, traj["u"], label="drive u")
    if args.controller == "composite":
        ax2.plot(t, traj["u2"], label="I-I part u2", alpha=0.7)
    ax2.set_ylabel("voltage (V)")
    ax2.set_xlabel("time (s)")
    ax2.legend()
    fig.suptitle(f"{args.controller}, reference {Path(args.reference).name}: e_mean = {metrics['e_mean_mm']:.4g} mm")
    atomic_savefig(fig, out / "tracking.png")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(8, 3))
    ax.plot(t, traj["error"])
    ax.set_xlabel("time (s)")
    ax.set_ylabel("tracking error y_d - y (mm)")
    atomic_savefig(fig, out / "error.png")
    plt.close(fig)
    atomic_write_json(out / "metrics.json", {**metrics, "settings": settings, "range_checks": range_checks})
    print(
        f"e_mean {metrics['e_mean_mm']:.4g} mm, rmse {metrics['rmse_mm']:.4g} mm, max |e| {metrics['max_abs_error_mm']:.4g} mm, "
        f"saturated {100 * metrics['saturated_fraction']:.1f}% -> {out}"
    )
    return 0
