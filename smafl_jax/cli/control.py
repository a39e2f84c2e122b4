"""``smafl control``: closed-loop PID / composite PID simulation of a saved model (paper section 4).

The workflow is `smafl_jax.workflows.control.run_control`; this module parses the arguments, shows the
workflow's notes and warnings on stderr and prints the result.  `add_loop_arguments`, `loop_options`,
`OPTION_NAMES` (and `workflow_lines_on_stderr`, from `cli._lines`) are shared with ``smafl sweep`` and ``smafl simulate``.
"""

from __future__ import annotations

from ._lines import workflow_lines_on_stderr


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
    p.add_argument(
        "--umax",
        type=float,
        default=None,
        help="upper drive limit, V (default 7.4, the paper's maximum test voltage; a note says when that lies above the "
        "plant model's trained input range); lower limit 0 V",
    )
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


#: How the workflows' error messages name their settings: as the commands' flags.
OPTION_NAMES = {
    "dt": "--dt",
    "duration": "--duration",
    "umax": "--umax",
    "tf": "--tf",
    "noise": "--noise",
    "quantum": "--quantum",
    "K": "--K",
    "kp": "--kp",
    "ki": "--ki",
    "kd": "--kd",
    "eval_start": "--eval-start",
    "model": "--model",
    "reference": "--reference",
    "controller": "--controller",
    "x": "--x",
    "y": "--y",
    "top": "--top",
    "calibrate": "--calibrate",
    "calibrate_fit": "--calibrate-fit",
    "measured": "--measured",
    "measured_sign": "--measured-sign",
    "metrics_file": "--metrics",
    "output_name": "--output-name",
    "method": "--method",
    "initial_state": "--initial-state",
}


def loop_options(args) -> dict:
    """The keyword arguments of `smafl_jax.workflows.control.build_loop` from the parsed loop options."""
    names = ("model", "plant", "reference", "controller", "kp", "ki", "kd", "tf", "K", "dt", "duration", "umax", "noise")
    names += ("quantum", "eval_start", "compensator_cascade", "seed")
    return {name: getattr(args, name) for name in names}


def add_parser(sub):
    p = sub.add_parser("control", help="closed-loop PID / composite PID (PID + I-I compensator) simulation")
    add_loop_arguments(p)
    p.add_argument("--out", required=True, help="output folder (tracking.png, error.png, trajectory.csv, metrics.json)")
    p.set_defaults(func=run)
    return p


def run(args):
    from ..workflows.control import run_control

    with workflow_lines_on_stderr():
        res = run_control(out=args.out, option_names=OPTION_NAMES, **loop_options(args))
    m = res.metrics
    print(
        f"e_mean {m['e_mean_mm']:.4g} mm, rmse {m['rmse_mm']:.4g} mm, max |e| {m['max_abs_error_mm']:.4g} mm, "
        f"saturated {100 * m['saturated_fraction']:.1f}% -> {res.out}"
    )
    return 0
