"""gyro-fmu on the command line: a short run writes its files; bad input gets a clear error."""

from __future__ import annotations

import json

import pytest

from gyro_fmu.cli import main


def test_run_writes_results_summary_and_figures(models_dir, tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", "--stop-time", "0.003", "--models", str(models_dir), "--out", str(out),
                 "--set", "kxy=6e7", "--rate", "sine:0.5:200", "--noise", "1e-5"])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["true_parameters"]["kxy"] == 6e7
    assert summary["scenario"]["rate"]["text"] == "sine:0.5:200:0"
    assert set(summary["unknowns"]) == {"Omega_z", "kxx", "kyy", "kxy", "dxx", "dyy", "dxy", "m"}
    for key in ("estimate_final", "sigma_final", "max_abs_error_tail",
                "converged_within_tolerance_at_s"):
        assert key in summary["unknowns"]["kxx"]
    assert "rms_error_tail" in summary["unknowns"]["Omega_z"]
    header = (out / "results.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "time" and "observer.Omega_hat" in header and "plant.x" in header
    assert (out / "fig3_states.png").stat().st_size > 10_000
    assert (out / "fig4_estimates.png").stat().st_size > 10_000
    assert "Omega_z" in capsys.readouterr().out
    assert main(["report", str(out)]) == 0


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["run", "--preset", "patent-table1"], "not positive definite"),
        (["run", "--set", "kxx"], "must read NAME=VALUE"),
        (["run", "--set", "kzz=1"], "unknown parameter"),
        (["run", "--set", "kxx=fast"], "'fast' is not a number"),
        (["run", "--rate", "wobble:1"], "kind must be one of"),
        (["run", "--step", "-1"], "argument --step: -1 must be > 0"),
        (["run", "--noise", "-0.1"], "argument --noise: -0.1 must be >= 0"),
        (["run", "--noise", "1e300"], "noise=1e+300 must lie in [0, 1e+06]"),
        (["run", "--Omega-z-0", "1e6"], "Omega_z_0=1000000.0 rad/s is not a rate this gyro"),
        (["run", "--initial", "mass=1"], "unknown initial guess"),
        (["report", "/nonexistent"], "summary.json not found"),
    ],
)
def test_bad_input_is_named_with_a_remedy(argv, message, capsys, models_dir, tmp_path):
    if argv[0] == "run":
        argv = [*argv, "--models", str(models_dir), "--out", str(tmp_path), "--stop-time", "1e-4"]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's refusal of an option's type
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_the_parser_imports_no_subcommand_stack():
    """Building `gyro-fmu`'s parser imports no command's stack (the self-calibration's
    scipy.optimize took 0.8 s of every command's start, numba's 0.7 s before it): each
    command imports what it needs when it runs."""
    import subprocess
    import sys

    code = ("import sys; from gyro_fmu.cli import parser; parser(); "
            "print(sorted(m for m in sys.modules if m.startswith(('scipy.optimize', 'numba', "
            "'matplotlib', 'gyro_fmu.selfcal.sequence', 'dask'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]", out
