"""Identification against jax-sysid (a general JAX system-identification package).

jax-sysid 1.1.0 pins ``jax<=0.4.31``, so it lives in its own virtual
environment, ``benchmarks/.sysid-venv`` (git-ignored), created here on first
use with ``python -m venv`` + ``pip install jax-sysid==1.1.0``.  Both sides fit
``datasets/main_loop.csv`` and predict the held-out ``datasets/minor_loop.csv``;
each runs in a fresh process, and the fit time is wall time of the fit call
with JIT compilation included (jax-sysid re-traces inside every ``fit`` call,
so a warm time is not comparable for it; ours is reported in the note).

* ours: `smafl_jax.fit` of a `Cascade` (thermal lag + EUPI, 29 parameters)
* jax-sysid: its README's residual-RNN nonlinear state-space model (nx = 5,
  8 + 8 hidden sigmoids, 1000 Adam + up to 1000 L-BFGS iterations), and its
  linear state-space model, on standardised data.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from ._common import progress, row

RATIO_MEANING = "baseline / ours (> 1: ours faster or more accurate)"
HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
VENV = HERE / ".sysid-venv"
SYSID_SPEC = "jax-sysid==1.1.0"


def _venv_python():
    return VENV / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def _tail(text, n=300):
    text = " ".join(str(text).split())
    return text[-n:]


def ensure_venv(timeout=900):
    """Create the jax-sysid venv if needed; return (python path, None) or (None, reason)."""
    py = _venv_python()
    probe = [str(py), "-c", "import jax_sysid, jax; print(jax.__version__)"]
    if py.exists() and subprocess.run(probe, capture_output=True, text=True).returncode == 0:
        return py, None
    progress(f"sysid: creating {VENV.relative_to(ROOT)} and installing {SYSID_SPEC} (one-off, a few minutes)")
    try:
        subprocess.run(
            [sys.executable, "-m", "venv", "--clear", str(VENV)], check=True, capture_output=True, text=True, timeout=120
        )
        pip = subprocess.run([str(py), "-m", "pip", "install", "-q", SYSID_SPEC], capture_output=True, text=True, timeout=timeout)
    except (subprocess.SubprocessError, OSError) as exc:
        return None, f"venv creation failed: {_tail(exc)}"
    if pip.returncode != 0:
        return None, f"pip install {SYSID_SPEC} failed: {_tail(pip.stderr or pip.stdout)}"
    chk = subprocess.run(probe, capture_output=True, text=True)
    if chk.returncode != 0:
        return None, f"jax-sysid installed but does not import: {_tail(chk.stderr)}"
    return py, None


def _run_json(cmd, timeout):
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    if proc.returncode != 0:
        raise RuntimeError(f"exit {proc.returncode}: {_tail(proc.stderr)}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run(quick: bool = False) -> list[dict]:
    train = str(ROOT / "datasets" / "main_loop.csv")
    test = str(ROOT / "datasets" / "minor_loop.csv")
    progress("sysid: our cascade fit (fresh process)")
    ours = _run_json([sys.executable, str(HERE / "_ours_fit_worker.py"), train, test], timeout=600)
    rows = []
    py, why = ensure_venv()
    epochs = 300 if quick else 1000
    base = None
    if py is not None:
        progress(f"sysid: jax-sysid fits ({epochs} Adam + {epochs} L-BFGS)")
        try:
            base = _run_json([str(py), str(HERE / "_sysid_worker.py"), train, test, "5", str(epochs)], timeout=900)
        except (RuntimeError, subprocess.SubprocessError, ValueError) as exc:
            why = f"jax-sysid worker failed: {_tail(exc)}"
    split = "train main_loop.csv (1761 samples), held out minor_loop.csv (1441)"
    note_ours = f"ours: Cascade, {ours['n_steps']} LM steps, warm re-fit {ours['fit_warm_s']:.2f} s; {split}"
    if base is None:
        for what, unit, val in (
            ("fit time (cold, compile incl.)", "s", ours["fit_s"]),
            ("held-out RMSE", "mm", ours["test_rmse"]),
        ):
            rows.append(row(f"identification vs jax-sysid: {what}", val, None, unit, note=f"jax-sysid not run: {why}"))
        return rows
    for kind in ("nonlinear", "linear"):
        b = base[kind]
        label = "jax-sysid residual RNN (nx=5)" if kind == "nonlinear" else "jax-sysid linear SS (nx=5)"
        extra = f"{label}, jax {base['jax']}; {note_ours}"
        rows.append(
            row(
                f"fit time (cold, compile incl.): ours vs {label}",
                ours["fit_s"],
                b["fit_s"],
                "s",
                ratio=b["fit_s"] / ours["fit_s"],
                note=extra,
                ours_warm_s=ours["fit_warm_s"],
            )
        )
        rows.append(
            row(
                f"held-out RMSE: ours vs {label}",
                ours["test_rmse"],
                b["test_rmse"],
                "mm",
                ratio=b["test_rmse"] / ours["test_rmse"],
                note=f"jax-sysid x0 = training x0 (both records start at rest); with x0 learned from the held-out "
                f"outputs (its README recipe): {b['test_rmse_learned_x0']:.4f} mm. Train RMSE ours "
                f"{ours['train_rmse']:.4f}, jax-sysid {b['train_rmse']:.4f} mm",
            )
        )
    return rows
