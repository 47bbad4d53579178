"""Careless input and Ctrl-C on the command line: one line with the cause and a remedy
(exit 2), the work so far kept (exit 130), never a traceback or a silent change.

Each test is one trial of the adversarial pass of issue 16; the FMU-side trials (states,
refusals, outputs) and the validate trials live in test_hostile_fmu.py and
test_hostile_validate.py.
"""

from __future__ import annotations

import json
import math
import os
import signal
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from gyro_fmu.cli import main
from gyro_fmu.cosim.master import CoSimulationError, CoSimulationInterrupted
from gyro_fmu.errors import GyroFmuError
from gyro_fmu.system.run import RunOutputError, load_results, run_and_report, write_or_rescue
from gyro_fmu.system.scenario import scenario


def _run(models_dir: Path, out: Path, *extra: str) -> list[str]:
    return ["run", "--models", str(models_dir), "--out", str(out), "--no-figures", *extra]


def _error(capsys) -> str:
    """stderr but the log's info lines ("FMUs in ..."): the error, its one line."""
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    return "\n".join(line for line in err.splitlines() if not line.startswith("FMUs in "))


def test_a_step_that_does_not_divide_the_run_is_refused_with_both_nearest_stop_times(
        models_dir, tmp_path, capsys):
    # it used to round 333.33 steps to 333 and end the run at 0.999 ms without a word
    assert main(_run(models_dir, tmp_path / "r", "--step", "3e-6", "--stop-time", "0.001")) == 2
    err = _error(capsys)
    assert "does not divide" in err and "0.000999 s or 0.001002 s" in err
    assert not (tmp_path / "r").exists()


def test_a_run_too_long_for_the_disk_is_refused_before_it_starts(models_dir, tmp_path, capsys):
    # it used to try to allocate 43.7 TiB and die in a MemoryError traceback; streamed to
    # disk, it filled 58 GB in 700 s before the disk refused
    start = time.perf_counter()
    assert main(_run(models_dir, tmp_path / "r", "--stop-time", "1e6")) == 2
    assert time.perf_counter() - start < 30
    err = _error(capsys)
    assert "GiB" in err and "GiB free" in err and "shorten the run" in err
    assert not (tmp_path / "r").exists(), "no empty output folder left behind"


def test_a_result_held_in_memory_too_large_is_refused_before_allocating(models_dir):
    from gyro_fmu.system.run import run_fmus

    with pytest.raises(GyroFmuError, match=r"more than the limit.*shorten the run"):
        run_fmus(scenario(stop_time=1e6), models_dir, ensure=False)


@pytest.mark.parametrize("where", ["a file", "under a file", "unreachable"])
def test_an_output_folder_that_cannot_be_made_is_one_line(models_dir, tmp_path, capsys, where):
    afile = tmp_path / "afile"
    afile.write_text("mine")
    out = {"a file": afile, "under a file": afile / "sub",
           "unreachable": Path("/proc/no/such/folder")}[where]
    assert main(_run(models_dir, out, "--stop-time", "0.001")) == 2
    err = _error(capsys)
    named = [str(d) for d in (out, *out.parents) if str(d) in err]
    assert named and "gyro-fmu: error:" in err and len(err.splitlines()) == 1
    assert afile.read_text() == "mine"


def test_results_that_cannot_be_written_are_rescued_not_lost(tmp_path):
    table = np.arange(6.0).reshape(3, 2)

    def write(path: Path) -> None:
        np.savetxt(path, table, delimiter=",")

    with pytest.raises(RunOutputError, match="the results are safe in") as caught:
        write_or_rescue(write, Path("/proc/no/such/folder/results.csv"))
    rescued = Path(str(caught.value).split("safe in ")[1].split(":")[0])
    assert np.array_equal(np.loadtxt(rescued, delimiter=","), table)


def test_debug_shows_the_traceback(models_dir, tmp_path):
    with pytest.raises(CoSimulationError, match="does not divide"):
        main([*_run(models_dir, tmp_path / "r", "--step", "3e-6", "--stop-time", "0.001"),
              "--debug"])


@pytest.mark.parametrize(
    ("fmu", "message"),
    [("plant=afile", "is not a readable FMU: File is not a zip file"),
     ("plant=.", "is a folder"),
     ("plant", "must read INSTANCE=PATH"),
     ("wheel=x.fmu", "INSTANCE one of drive, rate, plant, observer")])
def test_a_user_fmu_that_is_not_one_is_named(models_dir, tmp_path, capsys, fmu, message):
    os.chdir(tmp_path)
    Path("afile").write_text("not a zip")
    assert main(_run(models_dir, tmp_path / "r", "--stop-time", "0.001", "--fmu", fmu)) == 2
    assert message in _error(capsys)


def test_sweep_of_no_gyros_is_refused_by_the_parser(capsys):
    assert main(["sweep", "-n", "-3"]) == 2  # argparse's refusal, returned as the code
    assert "argument -n/--n: -3 is outside [1, inf]" in capsys.readouterr().err


def _csv(path: Path, header: str, rows: np.ndarray) -> Path:
    np.savetxt(path, rows, delimiter=",", header=header, comments="")
    return path


@pytest.mark.parametrize(
    ("rows", "message"),
    [(np.empty((0, 4)), "has a header but no rows"),
     ("time backwards", "time must increase from row to row: row 5"),
     ("text", "is not a numeric CSV")])
def test_identify_names_what_is_wrong_with_the_record(tmp_path, capsys, rows, message):
    path = tmp_path / "rec.csv"
    header = "time,drive.ux,plant.x,plant.y"
    if isinstance(rows, str) and rows == "text":
        path.write_text(header + "\n0,1,2,3\n0.1,one,2,3\n")
    elif isinstance(rows, str):
        t = np.arange(20) * 5e-6
        t[5] = t[3]  # it used to be called "a non-uniform step"
        _csv(path, header, np.column_stack([t, 0 * t, 0 * t, 0 * t]))
    else:
        _csv(path, header, rows)
    assert main(["identify", str(path)]) == 2
    assert message in _error(capsys)


@pytest.fixture
def a_run(models_dir, tmp_path) -> Path:
    out = tmp_path / "run"
    assert main(_run(models_dir, out, "--stop-time", "0.002")) == 0
    return out


@pytest.mark.parametrize("damage", ["summary not json", "summary of something else",
                                    "results truncated", "results without rows"])
def test_report_names_a_damaged_run(a_run, capsys, damage):
    summary, results = a_run / "summary.json", a_run / "results.csv"
    if damage == "summary not json":
        summary.write_text(summary.read_text()[:100])
    elif damage == "summary of something else":
        summary.write_text(json.dumps({"n": 3}))
    elif damage == "results truncated":
        results.write_bytes(results.read_bytes()[:20_000])
    else:
        results.write_text(results.read_text().splitlines()[0] + "\n")
    capsys.readouterr()
    assert main(["report", str(a_run)]) == 2
    err = _error(capsys)
    assert ("damaged" in err or "rows" in err) and "rerun the scenario" in err


def _interrupt_after(seconds: float) -> threading.Timer:
    """SIGINT to this process after `seconds`, as a terminal's Ctrl-C."""
    timer = threading.Timer(seconds, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    return timer


def _interrupt_when_stepping(folder: Path) -> tuple[threading.Thread, threading.Event]:
    """SIGINT to this process once the run in `folder` has written 200 kB of results (its
    stepping began), not after a fixed time: under load a fixed 0.5 s came during
    start-up, and the message (rightly) said so instead of the time reached. Set the
    event to stop watching (no signal then)."""
    stop = threading.Event()

    def watch() -> None:
        while not stop.wait(0.01):
            if any(p.stat().st_size > 200_000 for p in folder.glob(".results.csv.*.part")):
                os.kill(os.getpid(), signal.SIGINT)
                return

    thread = threading.Thread(target=watch)
    thread.start()
    return thread, stop


def test_ctrl_c_during_a_run_keeps_what_was_simulated_and_exits_130(models_dir, tmp_path,
                                                                     capsys, terminal_sigint):
    warm, out = tmp_path / "warm", tmp_path / "run"
    main(_run(models_dir, warm, "--stop-time", "0.004"))  # warm: kernels and archives loaded
    handler = signal.getsignal(signal.SIGINT)  # seen once: exit 0 in a full run (stop 39)
    watcher, stop = _interrupt_when_stepping(out)
    try:
        code = main(_run(models_dir, out, "--stop-time", "2"))
    finally:
        stop.set()
        watcher.join()
    err = _error(capsys)
    assert code == 130, (f"exit {code}; SIGINT handler before the run {handler!r}, "
                         f"after {signal.getsignal(signal.SIGINT)!r}; stderr: {err[-2000:]}")
    assert "interrupted at t =" in err and "wrote what was simulated" in err
    summary = json.loads((out / "summary.json").read_text())
    at = summary["interrupted"]["at_s"]
    assert 0 < at < 2
    result = load_results(out / "results.csv")
    assert result["time"][-1] == at and len(result["time"]) == round(at / 5e-6) + 1
    assert np.all(np.isfinite(result.data))


def test_ctrl_c_before_the_first_step_is_an_interrupt_with_nothing_written(
        models_dir, tmp_path, monkeypatch, terminal_sigint):
    import gyro_fmu.cosim.master as master

    real = master.instantiate

    def ctrl_c_while_instantiating(comp, callbacks):  # as in pythonfmu's start-up code
        os.kill(os.getpid(), signal.SIGINT)
        return real(comp, callbacks)

    monkeypatch.setattr(master, "instantiate", ctrl_c_while_instantiating)
    sc = scenario("default", stop_time=0.002)
    with pytest.raises(CoSimulationInterrupted, match="during start-up"):
        run_and_report(sc, tmp_path / "run", models_dir, figures=False)
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("again", [False, True])
def test_ctrl_c_after_the_simulation_keeps_results_with_their_summary(
        models_dir, tmp_path, monkeypatch, terminal_sigint, again):
    """Ctrl-C while the results are read back for the summary (found by
    benchmarks/interrupt_trials.py: results.csv and .parquet were left without
    summary.json): the summary is finished first, then the interrupt is raised, naming
    what is complete. A second Ctrl-C stops at once, leaving results that `gyro-fmu
    report` refuses (no summary) rather than a wrong pair."""
    import gyro_fmu.system.run as run

    real = run.read_back

    def ctrl_c_while_reading_back(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)
        if again:
            os.kill(os.getpid(), signal.SIGINT)
        return real(*args, **kwargs)

    monkeypatch.setattr(run, "read_back", ctrl_c_while_reading_back)
    sc = scenario("default", stop_time=0.002)
    out = tmp_path / "run"
    if again:
        with pytest.raises(KeyboardInterrupt, match="interrupted again"):
            run_and_report(sc, out, models_dir, figures=True)
        assert not (out / "summary.json").exists()
    else:
        with pytest.raises(KeyboardInterrupt, match="complete; the figures were not drawn"):
            run_and_report(sc, out, models_dir, figures=True)
        summary = json.loads((out / "summary.json").read_text())
        assert "interrupted" not in summary
        assert len(load_results(out / "results.csv")["time"]) == sc.n_steps + 1
        assert not list(out.glob("*.png"))
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_co_simulation_interrupted_carries_the_points_so_far(models_dir, terminal_sigint):
    from gyro_fmu.system.run import run_fmus

    sc = scenario("default", stop_time=2.0)
    timer = _interrupt_after(0.4)
    with pytest.raises(CoSimulationInterrupted) as caught:
        run_fmus(sc, models_dir, ensure=False)
    timer.join()
    result = caught.value.result
    assert result is not None and 1 < len(result["time"]) < sc.n_steps + 1
    assert np.all(np.isfinite(result.data))


def test_ctrl_c_during_a_sweep_keeps_every_finished_row(models_dir, tmp_path):
    from gyro_fmu.system.sweep import SweepSpec, ToleranceModel, run_sweep
    from gyro_fmu.system.sweep_report import write_outputs

    spec = SweepSpec(ToleranceModel("park-horowitz", {}, {"kxy": 0.05}), n=12,
                     stop_time=0.002, deadline=0.002)
    seen: list[dict] = []

    def ctrl_c_after_three(row: dict) -> None:
        seen.append(row)
        if len(seen) == 3:
            raise KeyboardInterrupt

    res = run_sweep(spec, models_dir, n_workers=1, progress=False, on_row=ctrl_c_after_three)
    assert res.interrupted == "interrupted after 3 of 12 gyros" and len(res.rows) == 3
    write_outputs(res, tmp_path / "sweep", figures=True)
    summary = json.loads((tmp_path / "sweep" / "summary.json").read_text())
    assert summary["n"] == 3 and summary["n_requested"] == 12 and summary["interrupted"]
    assert len((tmp_path / "sweep" / "sweep.csv").read_text().splitlines()) == 4


def test_inputs_that_ran_to_a_wrong_number_with_exit_0_are_refused(tmp_path, capsys):
    """0.2.0 ran each of these and exited 0: an Integer tuning given 1.5 (truncated to 1),
    a NaN or zero band for validate (everything 'matched'), an archive with a member
    outside its folder, a symbolic link or 10,001 members, sweep --workers 0 and a
    deadline past the stop time ('100 % within tolerance at 1000 ms' of a 4 ms run)."""

    from gyro_fmu.fmu.build import prebuilt_fmu
    from gyro_fmu.model.parameters import ParameterError
    from gyro_fmu.system.scenario import scenario
    from gyro_fmu.system.sweep import SweepSpec, ToleranceModel

    for tuning, why in (({"rate_model": 1.5}, "must be a whole number"),
                        ({"joseph": 0.5}, "must be a whole number"),
                        ({"nosuch": 1}, r"unknown tuning name\(s\) \['nosuch'\]")):
        with pytest.raises(ParameterError, match=why):
            scenario(tuning=tuning)
    plant = prebuilt_fmu("RateProfile")
    for band in (["--dy", "nan"], ["--dy", "1"], ["--dx", "0"]):
        assert main(["validate", *band, str(plant)]) == 2
    assert "argument --dx: 0 is outside [1, inf]" in capsys.readouterr().err
    from gyro_fmu.fmu.validate import validate_files

    for band in ({"dy": math.nan}, {"dy": 1.0}, {"dx": 0}):  # the library's own check
        with pytest.raises(ValueError, match=r"band d[xy]="):
            validate_files([plant], **band)
    from fmu_harness import hostile_archive

    bad = [hostile_archive(plant, kind, tmp_path / f"{kind}.fmu")
           for kind in ("dotdot", "symlink", "many")]
    assert main(["validate", *map(str, bad)]) == 1
    out = capsys.readouterr().out
    assert "'../evil.txt' would be unpacked outside the FMU's folder" in out
    assert "'resources/link' is a symbolic link" in out and "more than the 10000" in out
    assert main(["sweep", "--workers", "0"]) == 2
    model = ToleranceModel("park-horowitz", {}, {}, "uniform", 0)
    with pytest.raises(ParameterError, match="must be > 0 and at most the stop time"):
        SweepSpec(model, n=2, stop_time=0.004, deadline=1.0)
    with pytest.raises(ParameterError, match="must be > 0 and at most the stop time"):
        SweepSpec(model, n=2, stop_time=0.004, deadline=-0.001)
    with pytest.raises(ParameterError, match=r"noise seeds 2147483643 \.\. 2147483652"):
        SweepSpec(model, n=10, noise_seed=2**31 - 5)  # one seed per gyro: past the Integer


def test_careless_inputs_get_one_line_and_exit_2_not_a_traceback(tmp_path, capsys):
    """Each of these gave a Python traceback in 0.2.0 (and --drive a TypeError)."""
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"\xff\xfe\x00\x01binary")
    utf16 = tmp_path / "utf16.csv"
    utf16.write_text("time,drive.ux,plant.x,plant.y\n0,0,0,0\n", encoding="utf-16")
    notzip = tmp_path / "notzip.fmu"
    notzip.write_text("not a zip")
    cases = {
        ("identify", str(binary)): "is not a UTF-8 text CSV (byte 0xff at 0",
        ("identify", str(utf16)): "is not a UTF-8 text CSV",
        ("observability", "--window", "0"): "--window: 0 must be > 0",
        ("design-drive", "--window", "-1"): "--window: -1 must be > 0",
        ("design-drive", "--f-step", "0"): "--f-step: 0 must be > 0",
        ("design-drive", "--f-min", "7000"): "f_min=7000 Hz must be below f_max=6000 Hz",
        ("design-drive", "--force-limit", "1e300"): "over- or underflows double precision",
        ("container", "--step", "1e-3", "--models", str(tmp_path / "m")):
            "drive tone f1=4000 Hz is at or above the Nyquist",
        ("spec", "--startup-band", "10"): "startup_band=10 rad/s is wider than the full",
        ("doctor", "--fmu", str(notzip)): "is not an FMU the doctor can open",
        ("selfcal", "--drift", "0", "0"): "damping factor 0.0 must be a finite number > 0",
        ("run", "--drive", "nosuch=1"): "unknown --drive name(s) ['nosuch']",
        ("sweep", "-n", "2", "--scheduler", "tcp://:::1"): "cannot reach the Dask scheduler",
        ("design-drive", "--out", "/dev/full"): "--out /dev/full is not a file",
    }
    for argv, why in cases.items():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                code = main(list(argv))
            except SystemExit as exc:  # argparse's refusal
                code = exc.code
        # only a value out of the double range warns on its way to the refusal
        assert not caught or "1e300" in argv, (argv, [str(w.message) for w in caught])
        err = capsys.readouterr().err
        assert code == 2, (argv, err)
        assert why in err and "Traceback" not in err, (argv, err)


def test_drive_settings_reach_the_scenario():
    """--drive NAME=VALUE replaces the named tone settings and keeps the others."""
    from gyro_fmu.cli import parser
    from gyro_fmu.system.cli import scenario_from_args

    sc = scenario_from_args(parser().parse_args(["run", "--drive", "f1=4100", "--drive", "A2=0.5"]))
    d = sc.the_drive
    assert (d.A1, d.f1, d.A2, d.f2) == (1e-7, 4100.0, 0.5, 1200.0)
    assert d.ux(1e-4) == 1e-7 * math.sin(2 * math.pi * 4100 * 1e-4) + 0.5 * math.sin(
        2 * math.pi * 1200 * 1e-4)


def test_outputs_are_whole_and_known_to_belong_together(tmp_path, capsys):
    """results.csv and summary.json are renamed into place whole; the summary names its
    results by run id, rows and SHA-256, and report/identify refuse a pair that does not
    belong together; a folder a live run writes into is refused; a dead run's lock is
    taken over."""
    import subprocess
    import sys

    from gyro_fmu.outputs import LOCK

    a, b = tmp_path / "a", tmp_path / "b"
    for folder, seed in ((a, 1), (b, 2)):
        assert main(["run", "--stop-time", "0.0002", "--noise", "1e-4", "--seed", str(seed),
                     "--no-figures", "--out", str(folder)]) == 0
    summary = json.loads((a / "summary.json").read_text())
    assert summary["results"]["rows"] == 41 and len(summary["results"]["sha256"]) == 64
    assert not list(a.glob(".*.part")) and not (a / LOCK).exists()
    (a / "results.csv").write_bytes((b / "results.csv").read_bytes())  # a mixed pair
    capsys.readouterr()
    assert main(["report", str(a)]) == 2
    assert "belong to different runs" in capsys.readouterr().err
    assert main(["identify", str(a / "results.csv")]) == 2
    assert "belong to different runs" in capsys.readouterr().err
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (b / LOCK).write_text(str(holder.pid))
        assert main(["run", "--stop-time", "0.0002", "--no-figures", "--out", str(b)]) == 2
        assert f"being written by another gyro-fmu run (process {holder.pid})" in \
            capsys.readouterr().err
    finally:
        holder.kill()
        holder.wait()
    assert main(["run", "--stop-time", "0.0002", "--no-figures", "--out", str(b)]) == 0
    assert not (b / LOCK).exists()  # the dead run's lock was taken over, then released


def test_sigterm_is_handled_like_ctrl_c_and_leaves_no_unpacked_fmus(tmp_path):
    """0.2.0 died on SIGTERM with nothing written and 25 MB of unpacked FMUs left in
    TMPDIR. Now the run stops between chunks, writes what was simulated, exits 130 and
    removes its folders; folders a killed run left are swept by the next run."""
    import subprocess
    import sys
    import time

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    dead = tmp / "gyro_fmu_999999999_GyroPlant_x"  # a killed run's folder (no such pid)
    dead.mkdir()
    env = {**os.environ, "TMPDIR": str(tmp)}
    out = tmp_path / "run"
    # 4 s of simulated time: about 9 s of stepping with the native FMUs (2.3 s per s), so
    # the signal lands inside the co-simulation (at 1 s it came after the run, measured)
    proc = subprocess.Popen([sys.executable, "-m", "gyro_fmu.cli", "run", "--stop-time", "4",
                             "--no-figures", "--out", str(out)], env=env, cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not list(tmp.glob(f"gyro_fmu_{proc.pid}_GyroObserver_*")):  # stepping soon
        assert time.monotonic() < deadline and proc.poll() is None, proc.communicate()
        time.sleep(0.2)
    time.sleep(1.5)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "co-simulation interrupted at t = " in err and "wrote what was simulated" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"]["at_s"] > 0
    assert not dead.exists()
    assert not list(tmp.glob(f"gyro_fmu_{proc.pid}_*"))


def test_the_master_does_not_unpack_an_archive_that_climbs_out(tmp_path):
    import shutil
    import zipfile

    from gyro_fmu.cosim.master import Component, run_cosimulation
    from gyro_fmu.fmu.build import prebuilt_fmu

    fmu = tmp_path / "RateProfile.fmu"
    shutil.copy(prebuilt_fmu("RateProfile"), fmu)
    with zipfile.ZipFile(fmu, "a") as z:
        z.writestr("../../escaped.txt", "x")
    with pytest.raises(CoSimulationError, match="would be unpacked outside the FMU's folder"):
        run_cosimulation([Component("rate", fmu)], [], 1e-4, 5e-6)
    assert not (tmp_path.parent / "escaped.txt").exists()


@pytest.mark.parametrize("command", [
    ["sweep", "-n", "2"], ["selfcal"], ["ratetable"], ["selfcal-lot", "-n", "2"], ["spec"]])
def test_every_folder_writing_command_refuses_a_folder_a_live_run_holds(tmp_path, capsys,
                                                                        command):
    """sweep, the self-calibration commands and spec take the same lock as run: a folder
    another live process writes into is refused before any work, and left as it was."""
    import subprocess
    import sys

    from gyro_fmu.outputs import LOCK

    out = tmp_path / "busy"
    out.mkdir()
    (out / "summary.json").write_text("{}")
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (out / LOCK).write_text(str(holder.pid))
        assert main([*command, "--out", str(out)]) == 2
        assert f"being written by another gyro-fmu run (process {holder.pid})" in \
            capsys.readouterr().err
        assert sorted(p.name for p in out.iterdir()) == sorted([LOCK, "summary.json"])
    finally:
        holder.kill()
        holder.wait()


def test_ssp_given_an_existing_folder_writes_into_it_and_nothing_beside(models_dir, tmp_path,
                                                                       capsys):
    """`ssp --out DIR` on a folder left an 11 MB DIR.part beside it: the package now goes
    into the folder, written whole, and the user's files stay."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert main(["ssp", "--models", str(models_dir), "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["GyroSystem.ssp", "keep.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]
    assert f"wrote {out / 'GyroSystem.ssp'}" in capsys.readouterr().out
