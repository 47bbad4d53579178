"""`gyro-fmu datasheet`: GyroSensor's datasheet measured from the FMU's own output.

Writes datasheet.json (the figures, the protocol and the curves) and datasheet.png
(Allan deviation, step response, rate response) to --out (default runs/datasheet) and
prints the figures. --check measures with other seeds and holds the result against the
FMU's own documentation/datasheet.json: exit 1 with the figures that disagree.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from .. import options
from ..errors import GyroFmuError
from ..outputs import holds_out_folder, save_figure, write_json


def _parameter_names() -> tuple[str, ...]:
    from ..sensor.interface import SENSOR

    return tuple(v.name for v in SENSOR.variables if v.is_parameter)


def _preset(name: str) -> str:
    """A preset's name, checked when the option is used (the parser imports nothing)."""
    from ..sensor.presets import SENSOR_PRESETS

    if name not in SENSOR_PRESETS:
        raise argparse.ArgumentTypeError(f"{name!r} is no preset; known: "
                                         f"{', '.join(SENSOR_PRESETS)}")
    return name


def _seeds(text: str) -> tuple[int, ...]:
    try:
        seeds = tuple(options.seed(v) for v in text.split(",") if v.strip())
    except (ValueError, argparse.ArgumentTypeError):
        raise argparse.ArgumentTypeError(f"{text!r}: give seeds separated by commas, "
                                         "e.g. 1,2,3,4") from None
    if len(seeds) < 2:
        raise argparse.ArgumentTypeError(f"{text!r}: give at least 2 seeds (their spread is "
                                         "the uncertainty)")
    return seeds


def format_datasheet(sheet: dict) -> str:
    """The figures as a table: name, value, uncertainty, unit."""
    from ..sensor.datasheet_fmu import figure_text

    lines = [f"{'figure':<20} {'value':>12} {'+-':>10}  unit"]
    for name, f in sheet["figures"].items():
        value, u = figure_text(f)
        lines.append(f"{name:<20} {value:>12} {u:>10}  {f['unit']}")
    return "\n".join(lines)


def draw(sheet: dict, path: Path) -> Path:
    """Allan deviation, step response and rate response of every seed, in one figure."""
    from ..extras import pyplot

    plt = pyplot()
    import numpy as np

    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    for seed, c in sheet["curves"].items():
        ax[0].loglog(c["taus"], c["adev"], lw=1, label=f"seed {seed}")
        ax[1].plot([1e3 * t for t in c["step_t"]], c["step_y"], lw=1)
        r = c["response"]
        ax[2].semilogx([p["f_hz"] for p in r], [p["gain_db"] for p in r], "o-", ms=3, lw=1)
    f = sheet["figures"]
    tau = np.asarray(next(iter(sheet["curves"].values()))["taus"])
    for line, label in ((f["arw"]["value"] / np.sqrt(tau), "N / sqrt(tau)"),
                        (0.664 * f["bias_instability"]["value"] + 0 * tau, "0.664 B"),
                        (f["rate_random_walk"]["value"] * np.sqrt(tau / 3), "K sqrt(tau / 3)")):
        ax[0].loglog(tau, line, "k--", lw=0.8, alpha=0.6)
        ax[0].annotate(label, (tau[-1], line[-1]), fontsize=7, ha="right", va="bottom")
    ax[0].set(xlabel="tau (s)", ylabel="Allan deviation (rad/s)",
              title=f"rate 0 after {sheet['protocol']['warm_up_s']:g} s: "
                    f"B <= {f['bias_instability']['value']:.2g} rad/s")
    ax[0].legend(fontsize=7)
    ax[1].axvline(1e3 * f["latency"]["value"], color="k", ls=":", lw=1)
    ax[1].set(xlabel="time after the input step (ms)", ylabel="Omega_meas (rad/s)",
              title=f"step: latency {1e3 * f['latency']['value']:.2f} ms")
    ax[2].axhline(-3, color="k", ls=":", lw=1)
    ax[2].set(xlabel="frequency (Hz)", ylabel="gain (dB)",
              title=f"stepped sines: -3 dB at {f['bandwidth']['value']:.1f} Hz")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"{sheet['model']}: datasheet measured from its own output")
    fig.tight_layout()
    out = save_figure(fig, path, dpi=110)
    plt.close(fig)
    return out


@holds_out_folder("runs/datasheet")
def _cmd_datasheet(args: argparse.Namespace) -> int:
    from ..fmu.build import prebuilt_fmu
    from ..sensor.datasheet import CHECK_SEEDS, SEEDS, check_datasheet, measure_datasheet
    from ..sensor.datasheet_fmu import public, read_fmu_datasheet
    from ..sensor.presets import SENSOR_PRESETS

    fmu = Path(args.fmu) if args.fmu else prebuilt_fmu("GyroSensor")
    settings = {**SENSOR_PRESETS[args.preset], **dict(args.set or [])}
    out = Path(args.out or "runs/datasheet")
    if args.check:
        reference = read_fmu_datasheet(fmu, args.preset)
        if settings != reference.get("settings", {}):
            raise GyroFmuError(
                f"--check holds a measurement against {fmu.name}'s own datasheet of preset "
                f"{args.preset!r}, measured at its settings; --set {dict(args.set or [])} "
                "changes them: drop --set, or measure without --check")
    seeds = args.seeds or (CHECK_SEEDS if args.check else SEEDS)
    print(f"measuring {fmu.name} with seeds {list(seeds)} ...", flush=True)
    sheet = measure_datasheet(fmu, settings, seeds)
    write_json(out / "datasheet.json", sheet)
    print(format_datasheet(public(sheet)))
    if not args.no_figures:
        print(f"wrote {draw(sheet, out / 'datasheet.png')}")
    print(f"wrote {out / 'datasheet.json'}")
    if args.check:
        problems = check_datasheet(reference, sheet)
        for p in problems:
            print(f"FAIL {p}")
        print(f"{'FAIL' if problems else 'PASS'}: {len(reference['figures'])} figures of "
              f"{fmu.name}'s datasheet ({args.preset}) against seeds {list(seeds)}")
        return 1 if problems else 0
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add `gyro-fmu datasheet` to the command line."""
    d = sub.add_parser(
        "datasheet", help="measure GyroSensor.fmu's datasheet from its own output: bias, "
        "angle random walk, bias instability, scale factor, latency, bandwidth",
        description="Runs GyroSensor.fmu through fmpy under one protocol per seed (rate 0 "
        "after a warm-up, a step, stepped sines, +-10 rad/s) and prints each figure's mean "
        "and run-to-run spread; docs/datasheet.md. --check holds the FMU's own datasheet "
        "against other seeds (exit 1 on a figure outside its prediction interval).")
    d.add_argument("--fmu", help="GyroSensor FMU (default: the package's, FMI 2.0)")
    d.add_argument("--preset", type=_preset, default="consumer",
                   help="a realistic gyro: consumer (the FMU's defaults), high-q, low-cost "
                        "(gyro_fmu.sensor.presets); --set changes it further")
    d.add_argument("--set", action="append", metavar="NAME=VALUE",
                   type=options.assignment(_parameter_names, "bandwidth=50",
                                           "a GyroSensor parameter"),
                   help="a GyroSensor parameter (kxx ... m, kxx_0 ..., bandwidth, ...); "
                        "repeatable")
    d.add_argument("--seeds", type=_seeds, help="noise seeds, comma-separated (default "
                   "1-6; with --check 101,102)")
    d.add_argument("--check", action="store_true",
                   help="hold the FMU's documentation/datasheet.json against other seeds")
    d.add_argument("--out", help="output folder (default runs/datasheet)")
    d.add_argument("--no-figures", action="store_true", help="skip datasheet.png")
    d.set_defaults(func=_cmd_datasheet)
