"""Reliability of the CLI on bad input (issue 16): one clear line and exit 2, nothing left behind,
no silent success on invalid values, Ctrl-C -> 130, fast --help / --version, chunked sweeps with
progress, and the sampler's acceptance fraction after a resume.  One test per class of case."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.cli import main

ROOT = Path(__file__).resolve().parents[1]
DATASETS = ROOT / "datasets"
TRUTH = DATASETS / "truth.json"
RECORD = DATASETS / "minor_loop.csv"
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def _one_error_line(err, command):
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert lines, "no error message"
    assert "Traceback" not in err
    assert lines[-1].startswith(f"smafl {command}: error: "), lines[-1]
    return lines[-1]


def _short_record(tmp_path, n=200, scale=1.0, constant=False, output=True):
    d = np.genfromtxt(RECORD, delimiter=",", names=True)[:n]
    y = np.full(n, 1.5) if constant else d["displacement_mm"] * scale
    cols = {"time_s": d["time_s"], "voltage_V": d["voltage_V"]}
    if output:
        cols["displacement_mm"] = y
    path = tmp_path / f"rec_{n}_{scale:g}_{int(constant)}_{int(output)}.csv"
    sj.atomic_write_csv(path, cols)
    return path


# -- output paths ------------------------------------------------------------------------------------


def _bad_out_commands(tmp_path, out):
    rec = str(_short_record(tmp_path))
    return {
        "simulate": ["simulate", str(TRUTH), rec, "--out", out],
        "fit": ["fit", rec, "--model", "eupi", "--out", out],
        "control": ["control", "--model", str(TRUTH), "--duration", "1", "--out", out],
        "sweep": ["sweep", "--model", str(TRUTH), "--duration", "1", "--x", "kp=1,2", "--y", "ki=1,2", "--out", out],
        "diagnose": ["diagnose", rec, "--out", out],
        "check": ["check", rec, "--json", out],
    }


@pytest.mark.parametrize("where", ["proc", "sys", "file_as_folder", "folder_as_file"])
def test_unwritable_output_paths_exit_2_with_one_line(tmp_path, capsys, where):
    if where == "proc":
        out = "/proc/smafl_out/x"
    elif where == "sys":
        if not Path("/sys").is_dir() or (os.access("/sys", os.W_OK) and os.geteuid() != 0):
            pytest.skip("no read-only /sys here")
        out = "/sys/smafl_out"
    elif where == "file_as_folder":
        (tmp_path / "afile").write_text("x")
        out = str(tmp_path / "afile" / "out")
    else:
        (tmp_path / "adir").mkdir()
        out = str(tmp_path / "adir")
    wanted = {"proc": None, "sys": ("control", "check"), "file_as_folder": ("simulate", "fit", "check")}
    wanted["folder_as_file"] = ("simulate", "check")  # the others want a folder
    for command, args in _bad_out_commands(tmp_path, out).items():
        if wanted[where] is not None and command not in wanted[where]:
            continue
        before = sorted(p.name for p in tmp_path.iterdir())
        rc = main(args)
        err = capsys.readouterr().err
        assert rc == 2, (command, err)
        line = _one_error_line(err, command)
        assert out.split("/x")[0] in line or Path(out).name in line, line
        assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing created


def test_atomic_writer_failure_names_path_and_leaves_no_temp_file(tmp_path, monkeypatch):
    def refuse(src, dst):
        raise OSError(30, "Read-only file system")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(sj.UserInputError, match=r"result\.json: Read-only file system"):
        sj.atomic_write_json(tmp_path / "result.json", {"a": 1})
    assert list(tmp_path.iterdir()) == []


def test_read_only_output_folder_is_refused_before_any_work(tmp_path, monkeypatch):
    import tempfile

    real = tempfile.mkstemp

    def read_only(*a, dir=None, **k):
        if dir is not None and "ro" in Path(dir).parts:
            raise OSError(30, "Read-only file system")
        return real(*a, dir=dir, **k)

    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    (tmp_path / "ro").mkdir()
    with pytest.raises(sj.UserInputError, match=r"cannot write to output folder .*ro: Read-only"):
        sj.prepare_out_dir(tmp_path / "ro")
    with pytest.raises(sj.UserInputError, match="Read-only"):
        sj.prepare_out_dir(tmp_path / "ro" / "new")
    assert not (tmp_path / "ro" / "new").exists()  # the folder it created is removed again


# -- validation before anything is written -------------------------------------------------------------


def test_validation_errors_leave_nothing_behind(tmp_path, capsys):
    rec = str(_short_record(tmp_path))
    no_output = str(_short_record(tmp_path, output=False))
    empty_ref = tmp_path / "empty_ref.csv"
    empty_ref.write_text("")
    out = tmp_path / "new" / "out"
    m = str(tmp_path / "m.json")
    cases = [
        (["sample", rec, "--fit", str(TRUTH), "--steps", "50", "--burn", "80"], "--burn"),
        (["sample", rec, "--fit", str(TRUTH), "--gain-scale", "-1"], "--gain-scale"),
        (["sample", rec, "--fit", str(TRUTH), "--walkers", "2", "--steps", "20"], "walkers"),
        (["simulate", str(TRUTH), no_output, "--metrics", m], "--metrics"),
        (["control", "--model", str(TRUTH), "--kp", "-1"], "--kp"),
        (["control", "--model", str(TRUTH), "--reference", str(empty_ref)], "empty"),
        (["control", "--model", str(TRUTH), "--duration", "1e9"], "limit"),
        (["control", "--model", str(TRUTH), "--dt", "1e-9"], "limit"),
        (["sweep", "--model", str(TRUTH), "--x", "kp=-50:5:3", "--y", "ki=1,2"], "kp must be >= 0"),
        (["sweep", "--model", str(TRUTH), "--x", "K=0,1", "--y", "tf=0,1"], "tf must be > 0"),
    ]
    for args, expect in cases:
        target = str(tmp_path / "pred.csv") if args[0] == "simulate" else str(out)
        rc = main(args + ["--out", target])
        err = capsys.readouterr().err
        assert rc == 2, (args, err)
        assert expect in _one_error_line(err, args[0]), err
        assert not (tmp_path / "new").exists() and not (tmp_path / "pred.csv").exists(), args
        assert not Path(m).exists()


def test_rerun_names_the_earlier_runs_files_it_did_not_replace(tmp_path, capsys):
    """A rerun with --no-figures leaves an earlier run's figures beside the new fit.json: they are named, not removed."""
    rec = str(_short_record(tmp_path))
    out = tmp_path / "fit"
    out.mkdir()
    old = out / "fit_loops.png"
    old.write_bytes(b"an earlier run's figure")
    os.utime(old, (time.time() - 60, time.time() - 60))  # written a minute before this run
    (out / ".hidden").write_text("not a result")
    fast = ["--model", "eupi", "--max-steps", "0", "--n-sym", "3", "--n-alpha", "0", "--n-asym", "0", "--split", "none"]
    assert main(["fit", rec, *fast, "--no-figures", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    note = [line for line in err.splitlines() if "from an earlier run" in line]
    assert len(note) == 1 and "fit_loops.png" in note[0], err
    assert "fit.json" not in note[0] and "report.md" not in note[0] and ".hidden" not in note[0], note
    assert old.read_bytes() == b"an earlier run's figure"  # the user's earlier result is kept
    old.unlink()  # every remaining file is rewritten by a second run: nothing to name
    assert main(["fit", rec, *fast, "--no-figures", "--out", str(out)]) == 0
    assert "from an earlier run" not in capsys.readouterr().err


def test_failed_run_removes_only_the_empty_folder_it_created(tmp_path, capsys, monkeypatch):
    from smafl_jax.cli import control

    def boom(args):
        sj.prepare_out_dir(args.out)
        raise sj.UserInputError("late failure")

    monkeypatch.setattr(control, "run", boom)
    old = tmp_path / "old"
    old.mkdir()
    (old / "keep.txt").write_text("earlier results")
    assert main(["control", "--out", str(tmp_path / "a" / "b")]) == 2
    assert not (tmp_path / "a").exists()
    assert main(["control", "--out", str(old)]) == 2
    assert (old / "keep.txt").read_text() == "earlier results"

    def interrupted(args):
        sj.prepare_out_dir(args.out)
        raise KeyboardInterrupt

    monkeypatch.setattr(control, "run", interrupted)
    assert main(["control", "--out", str(tmp_path / "c")]) == 130
    assert capsys.readouterr().err.strip().endswith("smafl control: interrupted")
    assert not (tmp_path / "c").exists()


# -- silent success on invalid input ------------------------------------------------------------------


def test_model_file_with_nonpositive_constrained_parameter_is_refused(tmp_path):
    doc = json.loads(TRUTH.read_text())
    good = sj.model_from_dict(doc["model"])
    assert float(good.thermal.k1) > 0
    for path, value, ok in [
        (("thermal", "k1"), -1.0, False),
        (("thermal", "k1"), 0.0, False),
        (("hysteresis", "gain"), -0.5, False),
        (("hysteresis", "gain"), 0.0, True),  # a zero gain (non-negative least squares) is a valid model
        (("hysteresis", "poly"), [-5.0, 1.0], True),  # unconstrained field
    ]:
        d = json.loads(json.dumps(doc))
        d["model"][path[0]][path[1]] = value
        f = tmp_path / "m.json"
        f.write_text(json.dumps(d))
        if ok:
            sj.load_model(f)
        else:
            with pytest.raises(sj.UserInputError, match=f"model.{path[0]}.{path[1]}: must be"):
                sj.load_model(f)


def test_values_whose_squares_overflow_are_refused(tmp_path, capsys):
    huge = _short_record(tmp_path, scale=1e300)
    rc = main(["fit", str(huge), "--model", "eupi", "--out", str(tmp_path / "f")])
    assert rc == 2 and "too large" in _one_error_line(capsys.readouterr().err, "fit")
    assert not (tmp_path / "f").exists()
    rec = sj.load_record(huge)
    with pytest.raises(sj.UserInputError, match="too large"):
        sj.default_priors(["thermal.k1", "thermal.k2"], [(rec.u, rec.y, rec.dt)])
    # extreme but usable scales give finite priors (the k2 prior used to divide by umax**2 = 0 here)
    pri = sj.default_priors(["thermal.k2"], [(np.array([0.0, 1e-200]), np.array([0.0, 1.0]), 1.0)])
    assert np.isfinite(pri["thermal.k2"].loc)


def test_constant_output_is_an_error_for_fit_and_undefined_e_r_for_simulate(tmp_path, capsys):
    const = _short_record(tmp_path, constant=True)
    assert main(["fit", str(const), "--model", "eupi", "--out", str(tmp_path / "f")]) == 2
    assert "constant" in _one_error_line(capsys.readouterr().err, "fit")
    assert not (tmp_path / "f").exists()
    out = tmp_path / "p.csv"
    assert main(["simulate", str(TRUTH), str(const), "--out", str(out), "--measured", "displacement_mm"]) == 0
    text = capsys.readouterr().out
    assert "e_r undefined" in text and "nan" not in text


def test_oversized_csv_field_is_a_data_error(tmp_path):
    path = tmp_path / "big.csv"
    body = "".join(f"{0.1 * i},1,2\n" for i in range(20))
    path.write_text("time_s,voltage_V,displacement_mm\n" + body + "2.0," + "x" * 200_000 + ",1\n")
    with pytest.raises(sj.DataError, match="row 22"):
        sj.load_record(path)


def test_sample_refuses_a_model_it_cannot_condition():
    # a diagnose ExtendedModel is sampled now (its effect parameters with the rest); an object without
    # simulate(u, dt) is refused with a message naming it
    from smafl_jax.bayes import check_model_supported

    check_model_supported(sj.ExtendedModel(sj.load_model(TRUTH), ()))
    with pytest.raises(sj.UserInputError, match="no simulate"):
        check_model_supported(object())


# -- sweeps: chunks, progress, any values ---------------------------------------------------------------


def test_chunked_sweep_equals_one_call_and_reports_progress():
    from smafl_jax.control import PID, ClosedLoop, sine_reference, sweep

    model = sj.load_model(TRUTH)
    import jax.numpy as jnp

    base = ClosedLoop(plant=model, pid=PID(), reference=jnp.asarray(sine_reference(3.0, 0.05)))
    grid = {"pid.kp": np.linspace(0, 60, 5), "pid.ki": np.array([0.0, 5.0, 10.0])}
    calls = []
    chunked = sweep(base, 0.05, grid, chunk=4, progress=lambda d, n, t: calls.append((d, n)))
    whole = sweep(base, 0.05, grid)
    for k in whole.metrics:
        np.testing.assert_allclose(chunked.metrics[k], whole.metrics[k], rtol=1e-12, atol=1e-15)  # batch size: ulps
    assert [d for d, _ in calls] == [4, 8, 12, 15] and {n for _, n in calls} == {15}


def test_sweep_with_extreme_values_plots_and_writes_all(tmp_path, capsys):
    out = tmp_path / "sw"
    args = ["sweep", "--model", str(TRUTH), "--duration", "1", "--x", "kp=1e308,1", "--y", "ki=1,2", "--out", str(out)]
    assert main(args) == 0, capsys.readouterr().err
    for f in ("heatmap.png", "sweep.csv", "best.csv", "metrics.json"):
        assert (out / f).stat().st_size > 0
    assert "sweep: 4/4 configurations" in capsys.readouterr().err


# -- sampler resume ----------------------------------------------------------------------------------


def _joule_posterior():
    import jax.numpy as jnp

    rng = np.random.default_rng(7)
    u = np.zeros(120)
    u[10:] = 5.0
    u[60:] = 2.0
    truth = sj.JouleThermal(k1=jnp.asarray(0.0625), k2=jnp.asarray(0.055))
    y = np.asarray(truth.simulate(u, 0.5)) + 0.05 * rng.standard_normal(u.size)
    return sj.Posterior(truth, (u, y), 0.5)


def test_acceptance_fraction_is_counted_from_the_chain_and_survives_a_resume(tmp_path):
    import h5py

    from smafl_jax.bayes._bayes import _hdf_backend  # private: white-box test of the HDF5 backend

    post = _joule_posterior()
    ref = sj.run_sampler(post, 40, n_walkers=8, path=tmp_path / "ref.h5", seed=5, progress=False)
    be = _hdf_backend(tmp_path / "ref.h5", "mcmc", read_only=True)
    # uninterrupted: identical to emcee's own count
    np.testing.assert_array_equal(ref.acceptance_fraction, np.asarray(be.accepted) / be.iteration)
    # a hard kill between emcee's writes can leave `accepted` one step ahead of the chain
    path = tmp_path / "run.h5"
    sj.run_sampler(post, 25, n_walkers=8, path=path, seed=5, progress=False)
    with h5py.File(path, "a") as f:
        f["mcmc"]["accepted"][:] += 1
    run = sj.run_sampler(post, 40, n_walkers=8, path=path, seed=5, progress=False)
    assert run.resumed_from == 25
    np.testing.assert_array_equal(run.chain, ref.chain)
    np.testing.assert_array_equal(run.acceptance_fraction, ref.acceptance_fraction)
    np.testing.assert_array_equal(sj.load_run(path, post.names).acceptance_fraction, ref.acceptance_fraction)


# -- startup, version, interrupts (subprocesses) ---------------------------------------------------------


def test_help_and_version_do_not_import_jax():
    code = (
        "import sys\nfrom smafl_jax.cli import main\n"
        "for a in (['--help'], ['--version']):\n"
        "    try:\n        main(a)\n    except SystemExit as e:\n        assert e.code == 0\n"
        "print('JAX' if 'jax' in sys.modules else 'NOJAX')\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=ENV, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "usage: smafl" in r.stdout and f"smafl {sj.__version__}" in r.stdout
    assert r.stdout.strip().endswith("NOJAX")


def test_top_level_help_matches_the_command_modules():
    from smafl_jax.cli import COMMANDS, build_parser

    parser = build_parser("*")
    sub = next(a for a in parser._actions if a.dest == "command")
    assert {a.dest: a.help for a in sub._choices_actions} == COMMANDS


def _default_sigint():
    # test runners (xdist workers) may ignore or block SIGINT; both are inherited through exec
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


@pytest.mark.slow  # suite time (session 71: 17 s under load); Ctrl-C with a lost interrupt and SIGTERM stay in the default suite
def test_ctrl_c_exits_130_without_traceback_or_leftovers(tmp_path):
    out = tmp_path / "sweep_out"
    cmd = [sys.executable, "-m", "smafl_jax", "sweep", "--model", str(TRUTH), "--duration", "100"]
    cmd += ["--x", "kp=0:60:200", "--y", "K=0:20:200", "--out", str(out)]
    proc = subprocess.Popen(
        cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True, env=ENV, preexec_fn=_default_sigint
    )
    try:
        for line in proc.stderr:
            if line.startswith("  sweep:"):  # inside the computation, JAX's threads busy
                break
        proc.send_signal(signal.SIGINT)
        rest = proc.stderr.read()
        proc.wait(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, rest
    assert "Traceback" not in rest and rest.strip().endswith("smafl sweep: interrupted")
    assert not out.exists()


def test_heartbeat_reports_elapsed_time_while_a_phase_runs():
    import io
    import time

    from smafl_jax._progress import heartbeat  # private: white-box test; top-level, no public path

    buf = io.StringIO()
    with heartbeat("refinement", every_s=0.05, stream=buf):
        time.sleep(0.4)
    lines = buf.getvalue().splitlines()
    assert len(lines) >= 2 and all(ln.strip().startswith("refinement:") and ln.endswith("s elapsed") for ln in lines)
    n = len(lines)
    time.sleep(0.15)
    assert len(buf.getvalue().splitlines()) == n  # stopped with the block
    quiet = io.StringIO()
    with heartbeat("x", every_s=0.01, enabled=False, stream=quiet):
        time.sleep(0.05)
    assert quiet.getvalue() == ""


def _interrupt_when(cmd, marker, timeout=60, sig=signal.SIGINT):
    """Run ``cmd``, send ``sig`` once ``marker`` appears on stderr (the command is then busy); return (rc, stderr after)."""
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, env=ENV, preexec_fn=_default_sigint)
    seen = b""
    try:
        while marker.encode() not in seen:
            ch = proc.stderr.read(1)  # byte by byte: progress bars end lines with \r, not \n
            if not ch:
                break
            seen += ch
        proc.send_signal(sig)
        try:
            rest = proc.communicate(timeout=timeout)[1].decode(errors="replace")
        except subprocess.TimeoutExpired:
            rest = f"no exit within {timeout} s of the SIGINT (hung)"
    finally:
        proc.kill()
    return proc.returncode, seen.decode(errors="replace"), rest


# slow: one of three local runs hung after the SIGINT (a deadlock at interrupt, not yet understood); kept out of
# the default suite until that is fixed, run with `-m slow`
@pytest.mark.slow
@pytest.mark.parametrize("command", ["fit", "sample", "diagnose"])
def test_ctrl_c_during_fit_and_sample_exits_130_and_leaves_nothing_half_written(tmp_path, command):
    out = tmp_path / f"{command}_out"
    if command == "fit":
        cmd = [sys.executable, "-m", "smafl_jax", "fit", str(DATASETS / "steps.csv"), "--out", str(out), "--no-figures"]
        marker = "start candidate"  # inside the start screening
    elif command == "diagnose":
        cmd = [sys.executable, "-m", "smafl_jax", "diagnose", str(DATASETS / "main_loop.csv"), "--out", str(out)]
        marker = "diagnose: "  # the base fit is starting
    else:
        cmd = [sys.executable, "-m", "smafl_jax", "sample", str(RECORD), "--fit", str(TRUTH), "--out", str(out)]
        cmd += ["--steps", "100000"]
        marker = "sampling"  # the chain is starting or running
    rc, before, rest = _interrupt_when(cmd, marker)
    assert marker in before, before
    assert rc == 130, rest
    # sample adds what its chain holds and how to resume ("interrupted; N of M steps are saved in ...")
    assert "Traceback" not in rest and rest.strip().splitlines()[-1].startswith(f"smafl {command}: interrupted"), rest
    # no temporary files anywhere, and a fit writes nothing at all before it has a model
    leftovers = [p.name for p in tmp_path.rglob("*") if ".tmp" in p.name]
    assert not leftovers, leftovers
    if command in ("fit", "diagnose"):
        assert not out.exists() or not any(out.iterdir())


_SWALLOWING = """
import os, signal, sys, time
from pathlib import Path
from smafl_jax import cli, _io  # private: marks an atomic write in flight (_IN_FLIGHT)
from smafl_jax.cli import control

def stuck(args):
    tmp = Path(args.out) / ".half.tmp"  # an atomic write in progress when the interrupt comes
    tmp.parent.mkdir(parents=True, exist_ok=True)
    tmp.write_text("half")
    _io._IN_FLIGHT.add(str(tmp))
    # a handler that does nothing stands for a KeyboardInterrupt lost in a __del__ or held up by a long
    # compiled call: only the watchdog can end the process
    signal.signal(signal.SIGINT, lambda *a: None)
    print("busy", file=sys.stderr, flush=True)
    while True:
        time.sleep(0.05)

control.run = stuck
sys.argv = ["smafl", "control", "--out", sys.argv[1]]
sys.exit(cli.main())
"""


def test_ctrl_c_ends_the_process_even_when_the_interrupt_is_lost(tmp_path):
    out = tmp_path / "o"
    cmd = [sys.executable, "-c", _SWALLOWING, str(out)]
    t0 = time.monotonic()
    rc, before, rest = _interrupt_when(cmd, "busy", timeout=30)
    assert "busy" in before
    assert rc == 130, rest
    assert rest.strip().splitlines() == ["smafl control: interrupted"], rest
    assert 2.0 < time.monotonic() - t0 < 25  # ended by the watchdog (INTERRUPT_GRACE_S = 3 s after the Ctrl-C)
    assert not (out / ".half.tmp").exists()  # the temporary file of the unfinished write is removed


_TERMINATED = """
import sys, time
from pathlib import Path
from smafl_jax import cli, _io  # private: marks an atomic write in flight (_IN_FLIGHT)
from smafl_jax.cli import control

def busy(args):
    out = _io.prepare_out_dir(args.out, announce=False)
    tmp = out / ".half.tmp"  # an atomic write in progress when the SIGTERM comes
    tmp.write_text("half")
    _io._IN_FLIGHT.add(str(tmp))
    print("busy", file=sys.stderr, flush=True)
    while True:
        time.sleep(0.05)

control.run = busy
sys.argv = ["smafl", "control", "--out", sys.argv[1]]
sys.exit(cli.main())
"""


def test_sigterm_ends_the_run_as_ctrl_c_does_with_exit_143(tmp_path):
    """``kill`` / ``timeout`` / a batch scheduler send SIGTERM: Python's default ended the process at once and left the
    created output folder and the temporary file of an unfinished write behind (new-user trial)."""
    out = tmp_path / "a" / "o"
    cmd = [sys.executable, "-c", _TERMINATED, str(out)]
    rc, before, rest = _interrupt_when(cmd, "busy", timeout=30, sig=signal.SIGTERM)
    assert "busy" in before
    assert rc == 143, rest
    assert rest.strip().splitlines() == ["smafl control: terminated"], rest
    assert not (tmp_path / "a").exists()  # the folders this run created, and the temporary file in them, are gone


def test_usage_errors_are_one_line(capsys):
    cases = ((["check", "x.csv", "--bogus", "1"], "check"), (["fit", "--model", "nope", "x.csv"], "fit"), (["nosuch"], None))
    for args, command in cases:
        assert main(args) == 2
        err = capsys.readouterr().err
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert len(lines) == 1, err
        assert lines[0].startswith(f"smafl {command}: error: " if command else "smafl: error: ")
        assert "--help" in lines[0]


@pytest.mark.parametrize("kind", ["missing", "empty", "binary", "non_finite"])
def test_unreadable_input_records_exit_2_in_every_command(tmp_path, capsys, kind):
    bad = tmp_path / f"{kind}.csv"
    if kind == "empty":
        bad.write_text("")
    elif kind == "binary":
        bad.write_bytes(b"\x00\x01PK\x03\x04" * 20)
    elif kind == "non_finite":
        bad.write_text("time_s,voltage_V,displacement_mm\n0,1,2\n0.1,nan,2\n0.2,1,3\n")
    expect = {"missing": "file not found", "empty": "empty", "binary": "binary file", "non_finite": "row 3"}[kind]
    out = tmp_path / "new"
    cases = {
        "check": ["check", str(bad)],
        "fit": ["fit", str(bad), "--out", str(out)],
        "simulate": ["simulate", str(TRUTH), str(bad), "--out", str(out / "p.csv")],
        "diagnose": ["diagnose", str(bad), "--out", str(out)],
        "sample": ["sample", str(bad), "--fit", str(TRUTH), "--out", str(out)],
    }
    for command, args in cases.items():
        assert main(args) == 2, command
        line = _one_error_line(capsys.readouterr().err, command)
        assert bad.name in line and expect in line, line
        assert not out.exists(), command


def test_unreadable_model_files_and_missing_bundled_records_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    rec = str(_short_record(tmp_path))
    out = tmp_path / "new"
    cases = {
        "simulate": (["simulate", str(bad), rec, "--out", str(out / "p.csv")], "bad.json: not valid JSON"),
        "control": (["control", "--model", str(bad), "--out", str(out)], "bad.json: not valid JSON"),
        "sweep": (
            ["sweep", "--model", str(tmp_path / "no.json"), "--x", "kp=1,2", "--y", "ki=1,2", "--out", str(out)],
            "no.json",
        ),
        "sample": (["sample", rec, "--fit", str(bad), "--out", str(out)], "bad.json: not valid JSON"),
        "paper": (["paper", "--datasets", str(tmp_path), "--out", str(out)], "bundled records missing"),
    }
    for command, (args, expect) in cases.items():
        assert main(args) == 2, command
        assert expect in _one_error_line(capsys.readouterr().err, command)
        assert not out.exists(), command


# -- progress ----------------------------------------------------------------------------------------


def test_steps_report_progress_with_an_estimate():
    import io

    from smafl_jax._progress import Steps, format_seconds  # private: white-box test; top-level, no public path

    buf = io.StringIO()
    st = Steps("null records", 4, unit="records", every_s=0.0, stream=buf)
    for _ in range(4):
        time.sleep(0.02)
        st.advance(note="x")
    lines = buf.getvalue().splitlines()
    assert len(lines) == 4
    assert lines[0].strip().startswith("null records: 1/4 records,") and "about" in lines[0] and "left" in lines[0]
    assert lines[-1].strip().startswith("null records: 4/4 records,") and "left" not in lines[-1]
    # weighted steps: the estimate scales with the weight still to come
    w = Steps("cv", 2, every_s=1e9, enabled=False, weights=[1.0, 9.0])
    time.sleep(0.02)
    w.advance()
    # bracketed by the clock read before and after (remaining() reads it itself; a loaded machine moved it 4 ms between
    # two reads, 20 % of this step)
    before = w.elapsed()
    left = w.remaining()
    assert 9 * before <= left <= 9 * w.elapsed()
    assert format_seconds(5) == "5 s" and format_seconds(125) == "2 min 05 s" and format_seconds(3700) == "1 h 01 min"


def test_heartbeat_counts_the_steps_of_a_compiled_loop():
    import io

    import jax

    from smafl_jax._progress import count_step, heartbeat  # private: white-box test; top-level, no public path

    def body(i, x):
        jax.debug.callback(count_step)
        jax.debug.callback(lambda: time.sleep(0.03))
        return x + 1.0

    loop = jax.jit(lambda x: jax.lax.fori_loop(0, 20, body, x))
    buf = io.StringIO()
    with heartbeat("solver", every_s=0.1, stream=buf, max_steps=40):
        jax.block_until_ready(loop(0.0))
    count_step()  # outside any heartbeat: ignored
    lines = buf.getvalue().splitlines()
    with_steps = [ln for ln in lines if "of at most 40" in ln]
    assert with_steps, lines
    assert all(ln.endswith("left") for ln in with_steps)


def test_cli_shows_library_progress_and_quiet_hides_it(tmp_path, capsys, monkeypatch):
    from smafl_jax import _progress  # private: white-box test; top-level, no public path
    from smafl_jax.cli import diagnose

    def fake(args):
        st = _progress.Steps("phase", 2, every_s=0.0)
        st.advance()
        st.advance()
        return 0

    monkeypatch.setattr(diagnose, "run", fake)
    rec = str(_short_record(tmp_path))
    assert main(["diagnose", rec, "--out", str(tmp_path / "d")]) == 0
    assert "phase: 2/2" in capsys.readouterr().err
    assert main(["diagnose", rec, "--out", str(tmp_path / "d"), "--quiet"]) == 0
    assert "phase" not in capsys.readouterr().err
    # outside the CLI the library stays silent unless logging is configured
    _progress.Steps("phase", 1, every_s=0.0).advance()
    assert "phase" not in capsys.readouterr().err


def test_long_phases_report_progress(tmp_path, monkeypatch, caplog):
    """Preisach cross-validation and the LM refinement of a fit report with an estimate (tiny records)."""
    import logging

    from smafl_jax import _progress  # private: monkeypatch target (EVERY_S)
    from smafl_jax.models import cv_fit_preisach

    monkeypatch.setattr(_progress, "EVERY_S", 0.0)
    rng = np.random.default_rng(0)
    segs = []
    for top in (1.0, 0.8, 0.6, 0.4):
        u = np.r_[np.linspace(0, top, 15), np.linspace(top, 0, 15)]
        segs.append((u, np.tanh(2 * u) + 0.01 * rng.standard_normal(u.size)))
    with caplog.at_level(logging.INFO, logger="smafl_jax.progress"):
        cv_fit_preisach(segs, 0.0, 1.0, n_levels_grid=(4, 6), lam_grid=(1e-3,), everett=())
    msgs = [r.getMessage() for r in caplog.records]
    assert any("Preisach cross-validation: 1/2 grid sizes" in m and "about" in m for m in msgs), msgs
    assert any("Preisach cross-validation: 2/2 grid sizes" in m for m in msgs), msgs
    caplog.clear()
    monkeypatch.setattr(_progress, "EVERY_S", 0.01)
    rec = sj.load_record(_short_record(tmp_path))
    with caplog.at_level(logging.INFO, logger="smafl_jax.progress"):
        sj.fit(sj.EUPI.from_range(0.0, float(rec.u.max())), rec, max_steps=5, progress=True)
    assert any(r.getMessage().strip().startswith("joint refinement (lm):") for r in caplog.records)


def test_padded_calls_equal_unpadded_ones():
    import equinox as eqx
    import jax.numpy as jnp

    from smafl_jax.models import MIN_BUCKET, bucket_length, padded_call

    for n in (1, 37, MIN_BUCKET, MIN_BUCKET + 1, 1000, 4097, 100_000):
        b = bucket_length(n)
        assert b >= n and (n <= MIN_BUCKET or b <= 1.125 * n)
    assert len({bucket_length(n) for n in range(1, MIN_BUCKET + 1)}) == 1
    model = sj.load_model(TRUTH)
    rec = sj.load_record(RECORD)
    # one jitted function for both calls (eager op-by-op simulation and a new lambda per length cost 16 s here)
    sim = eqx.filter_jit(lambda m, x, dt: m.simulate(x, dt))
    for n in (50, 300, 777):
        u = np.asarray(rec.u[:n])
        direct = np.asarray(sim(model, jnp.asarray(u), rec.dt))
        padded = padded_call(sim, model, (u,), rec.dt)
        assert padded.shape == (n,)
        np.testing.assert_allclose(padded, direct, rtol=1e-13, atol=1e-14)


def test_ctrl_c_inside_a_destructor_ends_the_run_without_a_traceback(tmp_path):
    # Python cannot raise an exception out of __del__: it prints "Exception ignored in ..." with a traceback and
    # runs on; a Ctrl-C landing there must still end the command (exit 130, one line)
    code = (
        "import sys\nfrom smafl_jax import cli\nfrom smafl_jax.cli import control\n"
        "class Res:\n    def __del__(self):\n        raise KeyboardInterrupt\n"
        "def run(args):\n    r = Res()\n    del r\n    print('not interrupted', file=sys.stderr)\n    return 0\n"
        "control.run = run\nsys.argv = ['smafl', 'control', '--out', 'o']\nsys.exit(cli.main())\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=ENV, timeout=60, cwd=tmp_path)
    assert r.returncode == 130, r.stderr
    assert r.stderr.strip().splitlines() == ["smafl control: interrupted"], r.stderr


# -- figures: a unit on every axis ---------------------------------------------------------------------


def _labels_with_units(fig):
    """Every axis label of ``fig`` that is set names a unit in parentheses; returns the labels."""
    labels = []
    for ax in fig.axes:
        if not ax.axison:
            continue
        for label in (ax.get_xlabel(), ax.get_ylabel()):
            if label:
                assert "(" in label and label.rstrip().endswith(")"), f"axis label without a unit: {label!r}"
                labels.append(label)
    return labels


def test_report_figures_have_units_on_every_axis(tmp_path):
    import matplotlib.pyplot as plt

    import smafl_jax.report._report as _report  # private: patches atomic_savefig where _plot looks it up; calls _plot
    from smafl_jax import report as pb
    from smafl_jax.diagnosis import make_split
    from smafl_jax.report import axis_label

    assert axis_label("displacement_mm") == "displacement (mm)"
    assert axis_label("temperature_front_C") == "temperature front (°C)"
    assert axis_label("length_signal") == "length signal (unit not given)"  # says so instead of inventing one
    assert axis_label("pos", {"pos": "mm"}) == "pos (mm)"
    assert axis_label("displacement [mm]") == "displacement (mm)" and axis_label("stroke (mm)") == "stroke (mm)"
    rng = np.random.default_rng(1)
    s = rng.normal(size=(400, 2))
    figs = [pb.corner_figure(s, ["thermal.k1", "noise.sigma"], output_unit="mm")]
    figs.append(pb.trace_figure(s.reshape(50, 8, 2), ["thermal.k1", "noise.sigma"], 10, output_unit="mm"))
    t = np.arange(30.0)
    f = rng.normal(size=(5, 30))
    figs.append(pb.predictive_time_figure(t, t, f, f, np.ones(30, bool), ylabel="displacement_mm")[0])
    figs.append(pb.predictive_loop_figure(t, t, f, np.ones(30, bool), xlabel="voltage_V", ylabel="displacement"))
    labels = [lab for fig in figs for lab in _labels_with_units(fig)]
    assert "thermal.k1 (1/s)" in labels and "noise.sigma (mm)" in labels and "displacement (mm)" in labels
    for fig in figs:
        plt.close(fig)
    # the diagnosis plot, on the output column's unit
    rec = sj.load_record(_short_record(tmp_path, n=300))
    split = make_split(rec)
    captured = []
    orig = _report.atomic_savefig
    try:
        _report.atomic_savefig = lambda fig, path: captured.append(fig)
        _report._plot(tmp_path / "r.png", split, lambda seg: seg.y, "t", axis_label(rec.output_name))
    finally:
        _report.atomic_savefig = orig
    assert {"displacement\n(mm)", "residual\n(mm)"} <= set(_labels_with_units(captured[0]))
