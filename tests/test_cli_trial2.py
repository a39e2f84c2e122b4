"""Findings of the session-36 new-user trial 2 (/tmp/s36/trial2): a Ctrl-C during `smafl sample` ends without emcee's
dump and says how to resume, the sample band warning names the output and its unit, `smafl control` warns of
references the plant cannot reach and of an --umax outside the trained range, the catalogue's tanh slope never
overflows, and the small CLI notes (sweep size, NaN reference row, created output folder)."""

import json
import os
import signal
from pathlib import Path

import h5py
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.cli import main

DATASETS = Path(__file__).resolve().parents[1] / "datasets"
TRUTH = DATASETS / "truth.json"


def _short_record(path, n):
    d = np.genfromtxt(DATASETS / "minor_loop.csv", delimiter=",", names=True)[:n]
    sj.atomic_write_csv(path, {"time_s": d["time_s"], "voltage_V": d["voltage_V"], "displacement_mm": d["displacement_mm"]})
    return path


# -- 6: Ctrl-C during sampling ------------------------------------------------------------------------------------


@pytest.mark.slow  # suite time (16 s: a sample run, interrupted, then resumed); interrupts: tests/test_reliability.py
def test_ctrl_c_while_sampling_says_what_is_saved_and_how_to_resume(tmp_path, capsys, monkeypatch):
    """A real SIGINT in the middle of the sampler (inside the log-density, where the time goes): exit 130, one line with
    the steps saved and the command that resumes, none of emcee's dump of the walkers (it printed one for any exception
    in the density, a KeyboardInterrupt too); the rerun of that command resumes from those steps."""
    from smafl_jax.bayes import Posterior

    rec = _short_record(tmp_path / "rec.csv", 400)
    out = tmp_path / "s"
    argv = ["sample", str(rec), "--fit", str(TRUTH), "--out", str(out), "--steps", "30", "--walkers", "8"]
    argv += ["--draws", "10", "--no-progress", "--restart"]
    density = Posterior.__call__
    calls = []

    def interrupted(self, thetas):
        calls.append(1)
        if len(calls) == 8:  # the start, then two half-moves per step: a few steps saved, the next cut short
            os.kill(os.getpid(), signal.SIGINT)
        return density(self, thetas)

    monkeypatch.setattr(Posterior, "__call__", interrupted)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # test runners may ignore SIGINT
    try:
        rc = main(argv)
    except KeyboardInterrupt:
        pytest.fail("the interrupt escaped the command")
    finally:
        signal.signal(signal.SIGINT, previous)
    cap = capsys.readouterr()
    assert rc == 130
    assert "emcee" not in cap.out + cap.err and "Traceback" not in cap.err, cap
    last = cap.err.strip().splitlines()[-1]
    chain = out / "chain.h5"
    with h5py.File(chain, "r") as f:
        saved = int(f["mcmc"].attrs["iteration"])
    assert 0 < saved < 30
    head = f"smafl sample: interrupted; {saved} of 30 steps are saved in {chain}; resume with: smafl sample "
    assert last.startswith(head), last
    again = last.split("resume with: ")[1].split()
    assert again[1:] == [a for a in argv if a != "--restart"]  # the same command, without the flag that discards
    monkeypatch.setattr(Posterior, "__call__", density)
    assert main(again[1:]) == 0
    assert f"resuming {chain} at step {saved} of 30" in capsys.readouterr().err


def test_interrupt_line_takes_the_commands_note_and_the_resume_command_drops_restart(monkeypatch):
    """The line the watchdog thread prints too (`_interrupted_text`): the note, none when it fails; the command shown to
    resume drops --restart (also abbreviated, as argparse accepts it) and keeps everything else, quoted for a shell."""
    from smafl_jax import cli

    monkeypatch.setitem(cli._run, "argv", ["sample", "my rec.csv", "--fit", "f.json", "--rest", "--steps", "50"])
    assert cli.command_line(drop=("--restart",)) == "smafl sample 'my rec.csv' --fit f.json --steps 50"
    monkeypatch.setitem(cli._run, "note", lambda: "7 of 50 steps are saved")
    assert cli._interrupted_text("smafl sample") == "smafl sample: interrupted; 7 of 50 steps are saved"
    monkeypatch.setitem(cli._run, "note", lambda: 1 / 0)
    assert cli._interrupted_text("smafl sample") == "smafl sample: interrupted"


def test_interrupt_is_held_until_a_chain_write_ends():
    """The sampler's HDF5 writes run with Ctrl-C held back: the KeyboardInterrupt comes after the block, not in it."""
    from smafl_jax.bayes._bayes import _interrupt_deferred  # private: the guard of emcee's save_step

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    done = []
    try:
        with pytest.raises(KeyboardInterrupt):
            with _interrupt_deferred():
                os.kill(os.getpid(), signal.SIGINT)
                done.append(sum(range(1000)))  # bytecodes after the signal: the handler would have raised here
                done.append(True)
        assert done == [499500, True]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, previous)


# -- 7: the sample band warning names the output, its unit, and a band wider than the output's span -----------------


def test_band_warning_states_the_output_its_unit_and_a_meaningless_band(tmp_path, monkeypatch):
    from smafl_jax.workflows import sample as W

    monkeypatch.setattr(W, "_where_untrained", lambda *a: None)  # the reason is another check's; here: the wording
    n = 100
    t = np.arange(n) * 0.1
    path = tmp_path / "r.csv"
    sj.atomic_write_csv(path, {"time_s": t, "voltage_V": np.ones(n), "stroke [mm]": np.linspace(0, 1, n)})
    rec = sj.load_record(path, output="stroke [mm]")
    mask = np.arange(n) < 60  # the last 40 held out
    width = np.where(mask, 0.001, 0.5)
    width[90:] = 7.0  # wider than the 5 mm the output spans in the sampled part
    fq = np.stack([-width / 2, np.zeros(n), width / 2])
    text = W._unconstrained(None, rec, 0, mask, fq, 0.01, None, y_span=5.0)
    assert "model output (stroke [mm]) is wider than 4 noise SDs (up to 7 mm; noise SD 0.01 mm)" in text, text
    assert "on 10 of them (from 9 s) the band is wider than the whole span the output covers in the sampled data (5 mm)" in text
    assert "meaningless" in text
    width[90:] = 4.0  # within the span: no such clause
    text = W._unconstrained(None, rec, 0, mask, np.stack([-width / 2, np.zeros(n), width / 2]), 0.01, None, y_span=5.0)
    assert "40 of 40 held-out samples" in text and "meaningless" not in text


# -- 8: control: references out of reach, the default drive limit ----------------------------------------------------


@pytest.fixture(scope="module")
def narrow(tmp_path_factory):
    """The bundled true cascade saved as if trained on 0-2 V drives."""
    path = tmp_path_factory.mktemp("trial2") / "narrow.json"
    data = {"input_column": "voltage_V", "output_column": "displacement_mm", "input_range": [0.0, 2.0]}
    sj.save_model(path, sj.load_model(TRUTH), data=data)
    return path


def test_reference_out_of_reach_is_warned_with_the_range_the_loop_really_reaches(narrow, tmp_path):
    """A reference far above / below what the plant reaches with its drive in [0, umax]: the warning's reachable range
    is where the closed loop itself ends up (drive saturated at umax for 5 thermal time constants, or at rest at 0 V)."""
    k1 = float(sj.load_model(TRUTH).thermal.k1)
    n = int(6.0 / k1 / 0.1)
    kw = {"controller": "pid", "dt": 0.1, "umax": 5.0}
    high = sj.run_control(narrow, reference=np.full(n, 8.0), out=tmp_path / "h", **kw)
    check = json.loads(high.files["metrics.json"].read_text())["settings"]["reference_check"]
    assert check == high.settings["reference_check"]
    lo, hi = check["reachable_output_mm"]
    assert high.trajectory["u"][-50:].min() == 5.0  # saturated at the limit
    assert hi == pytest.approx(high.trajectory["y"][-1], rel=5e-3)
    assert check["n_above"] == n and check["n_below"] == 0
    assert f"{n} of {n} reference samples (100.0 %) are out of reach ({n} above, 0 below" in high.warnings[0]
    low = sj.run_control(narrow, reference=np.full(n, -1.0), out=tmp_path / "l", **kw)
    assert low.trajectory["u"].max() == 0.0 and lo == pytest.approx(low.trajectory["y"].min(), rel=1e-6)
    assert "(0 above, " in low.warnings[0]
    inside = sj.run_control(narrow, reference=np.full(n, 0.5 * (lo + hi)), out=tmp_path / "i", **kw)
    assert not any("out of reach" in w for w in inside.warnings)


def test_sweep_warns_before_it_runs_when_the_reference_is_out_of_reach_at_the_largest_swept_umax(narrow, tmp_path):
    """The sweep ranks gains on the reference it is given: one the plant cannot reach ranks them by how they saturate.
    The reach is taken at the largest swept umax, so a reference reachable only with the larger limits is not warned."""
    from smafl_jax.control import reachable_output

    k1 = float(sj.load_model(TRUTH).thermal.k1)
    n = int(6.0 / k1 / 0.1)
    kw = {"controller": "pid", "dt": 0.1, "progress": False}
    lo3, hi3 = reachable_output(sj.load_model(narrow), 3.0)
    _, hi5 = reachable_output(sj.load_model(narrow), 5.0)
    between = np.full(n, 0.5 * (hi3 + hi5))  # out of reach at 3 V, within reach at 5 V
    swept = sj.run_sweep("umax=3,5", "kp=1,2", narrow, reference=between, out=tmp_path / "s", **kw)
    assert swept.settings["reference_check"]["checked"] and not any("out of reach" in w for w in swept.warnings)
    low = sj.run_sweep("umax=2,3", "kp=1,2", narrow, reference=between, out=tmp_path / "l", **kw)
    assert low.warnings[0].endswith("(at the largest swept umax, 3 V)") and f"{n} of {n} reference samples" in low.warnings[0]
    written = json.loads(low.files["metrics.json"].read_text())["settings"]["reference_check"]
    assert written["n_above"] == n and written["drive_range_V"] == [0.0, 3.0]
    fixed = sj.run_sweep("kp=1,2", "ki=0,0.1", narrow, reference=between, out=tmp_path / "f", umax=3.0, **kw)
    assert "out of reach" in fixed.warnings[0] and "largest swept" not in fixed.warnings[0]
    assert 0.5 * (hi3 + hi5) > hi3 > lo3


def test_control_cli_notes_the_default_umax_and_created_folders_and_names_a_nan_row(narrow, tmp_path, capsys):
    ref = tmp_path / "ref.csv"
    t = np.arange(40) * 0.05
    sj.atomic_write_csv(ref, {"time_s": t, "reference_mm": np.full(40, 9.0)})
    out = tmp_path / "a" / "b" / "c"
    argv = ["control", "--model", str(narrow), "--reference", str(ref), "--controller", "pid", "--dt", "0.05"]
    assert main([*argv, "--out", str(out)]) == 0
    err = capsys.readouterr().err
    note = "note: no --umax given: the drive is limited to 7.4 V (the paper's maximum test voltage), above the input range"
    assert f"{note} [0, 2] V" in err
    assert "pass --umax 2 to stay inside it" in err
    assert "warning: reference ref.csv spans [9, 9] mm" in err and "out of reach (40 above, 0 below" in err
    assert f"note: created the folder {out} and the missing folders above it ({tmp_path / 'a'}, {tmp_path / 'a' / 'b'})" in err
    # a NaN cell: the error names its row (the file's line) and how many there are
    r = np.full(40, 2.0)
    r[[7, 9]] = np.nan
    bad = tmp_path / "nan.csv"
    sj.atomic_write_csv(bad, {"time_s": t, "reference_mm": r})
    assert main(["control", "--model", str(narrow), "--reference", str(bad), "--out", str(tmp_path / "n")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"smafl control: error: {bad}, row 9: 'reference_mm' is 'nan' (2 such rows in all)"), err


# -- 9: the saturation effect's slope --------------------------------------------------------------------------------


def test_saturation_slope_is_finite_and_silent_far_out_and_unchanged_near():
    import warnings

    from smafl_jax.effects.catalogue import OutputSaturation

    link = OutputSaturation(m=np.asarray(1.0), w=np.asarray(0.01)).profile_link()
    z = np.concatenate([np.linspace(0.7, 1.3, 601), [-1e6, 1e6, 1e300]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the old 1 / cosh(x)**2 warned "overflow encountered in square" here
        with np.errstate(all="raise"):
            s = link.slope(z)
    assert np.all(np.isfinite(s)) and np.all(s >= 0) and np.all(s[-3:] < 1e-300)
    near = z[:601]
    with np.errstate(over="ignore"):
        old = 1.0 / np.cosh((near - 1.0) / 0.01) ** 2
    np.testing.assert_allclose(s[:601], old, rtol=1e-13, atol=0)
    h = 1e-7  # and it is the forward map's derivative
    fd = (link.forward(near + h) - link.forward(near - h)) / (2 * h)
    np.testing.assert_allclose(s[:601], fd, rtol=1e-5, atol=1e-9)


# -- 10: small notes ---------------------------------------------------------------------------------------------------


def test_a_long_sweep_gets_a_note_with_its_expected_time_from_the_second_batch(caplog):
    import logging

    from smafl_jax.workflows.sweep import LONG_SWEEP_S, _progress_logger  # private: the note's rule, without a sweep

    caplog.set_level(logging.INFO)
    report = _progress_logger(every_s=1e9, size="200000 configurations (2 kp x 100000 K) x 4000 samples")
    report(1000, 200000, 9.0)  # the first batch includes the compilation: not used for the estimate
    report(2000, 200000, 12.0)  # 1000 configurations in 3 s: 198 000 more take 594 s
    notes = [r.getMessage() for r in caplog.records if r.getMessage().startswith("note: a long sweep")]
    assert notes == [
        "note: a long sweep: 200000 configurations (2 kp x 100000 K) x 4000 samples: about 10 min in all at the rate of "
        "the second batch (1000 configurations in 3 s); Ctrl-C stops it and writes nothing"
    ]
    caplog.clear()
    quick = _progress_logger(every_s=1e9)
    quick(1000, 3000, 9.0)
    quick(2000, 3000, 10.0)  # about 11 s in all
    assert LONG_SWEEP_S > 11 and not [r for r in caplog.records if "long sweep" in r.getMessage()]


def test_sample_help_says_steps_is_at_least_10(capsys):
    with pytest.raises(SystemExit):
        main(["sample", "--help"])
    assert "chain length per walker, at least 10" in " ".join(capsys.readouterr().out.split())


def test_a_sweep_axis_the_loop_cannot_feel_is_said_with_the_saturation_behind_it():
    """A flat axis on the heat map (a new-user trial: K swept on a loop whose drive sat at its limit) is said, and the
    saturation named when the drive is saturated on most samples; an axis that moves e_mean is not."""
    from smafl_jax.workflows.sweep import FLAT_AXIS_RTOL, sweep_flat_axes

    kp, K = np.array([1.0, 2.0, 4.0]), np.array([0.0, 5.0])
    e = np.outer(1.0 / kp, 1.0 + 0.2 * FLAT_AXIS_RTOL * np.array([0.0, 1.0]))  # kp moves e_mean, K by 0.2 % of the limit
    saturated = np.full(e.shape, 0.8)
    doc = sweep_flat_axes({"e_mean_mm": e, "saturated_fraction": saturated}, {"kp": kp, "K": K})
    assert not doc["kp"]["flat"] and "warning" not in doc["kp"]
    assert doc["K"]["flat"] and doc["K"]["spread"] == pytest.approx(0.2 * FLAT_AXIS_RTOL, rel=1e-9)
    assert "along K" in doc["K"]["warning"] and "saturated on a median 80 %" in doc["K"]["warning"]
    calm = sweep_flat_axes({"e_mean_mm": e, "saturated_fraction": 0 * saturated}, {"kp": kp, "K": K})
    assert "saturated" not in calm["K"]["warning"]
    # a NaN cell (a diverged configuration) is skipped, not propagated; one value on an axis: nothing to say about it
    e_nan = e.copy()
    e_nan[0, 1] = np.nan
    one = sweep_flat_axes({"e_mean_mm": e_nan, "saturated_fraction": saturated}, {"kp": kp, "K": K})
    assert one["K"]["flat"] and np.isfinite(one["K"]["spread"])
    single = sweep_flat_axes({"e_mean_mm": e[:, :1], "saturated_fraction": saturated[:, :1]}, {"kp": kp, "K": K[:1]})
    assert "K" not in single and not single["kp"]["flat"]
