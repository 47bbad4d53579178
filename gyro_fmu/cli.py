"""Command line `gyro-fmu`: build the FMUs, run a scenario, report on a run."""

from __future__ import annotations

import argparse
import sys
import textwrap
import warnings
from pathlib import Path

from . import __version__, options
from .errors import GyroFmuError
from .logs import command_logging

#: The options of how much a command says (anywhere on the line, as --debug).
QUIET, VERBOSE = ("-q", "--quiet"), ("-v", "--verbose")


def _cmd_build(args: argparse.Namespace) -> int:
    from .fmu.build import FMU_NAMES, PYTHONFMU_NAMES, build_all

    names = PYTHONFMU_NAMES if args.flavour == "pythonfmu" else FMU_NAMES
    for path in build_all(Path(args.dest), names, flavour=args.flavour):
        print(f"built {path.resolve()}")
    return 0


def _cmd_fmus(args: argparse.Namespace) -> int:
    from .fmu.build import NATIVE_NAMES, copy_fmu, prebuilt_fmu

    dest = Path(args.dest)
    for version in (2, 3) if args.fmi == "both" else (int(args.fmi),):
        for name in NATIVE_NAMES:
            folder = dest / f"fmi{version}" if args.fmi == "both" else dest
            print(f"wrote {copy_fmu(prebuilt_fmu(name, version), folder).resolve()}")
    return 0


def examples_dir() -> Path:
    """The example scripts: gyro_fmu/examples of an installation, examples/ of a checkout."""
    from importlib.util import find_spec

    spec = find_spec("gyro_fmu.examples")
    for root in [*(spec.submodule_search_locations or [] if spec else []),
                 Path(__file__).resolve().parents[1] / "examples"]:
        if any(Path(root).glob("*.py")):
            return Path(root)
    raise GyroFmuError("the example scripts are not in this installation of gyro_fmu: "
                       "reinstall it (pip install --force-reinstall gyro_fmu)")


def _cmd_examples(args: argparse.Namespace) -> int:
    import shutil

    dest = Path(args.dest)
    sources = sorted(p for p in examples_dir().iterdir() if p.suffix in (".py", ".sh"))
    clash = [p.name for p in sources if (dest / p.name).exists()
             and (dest / p.name).read_bytes() != p.read_bytes()]
    if clash and not args.force:
        raise GyroFmuError(f"{dest} holds other files named {', '.join(clash)}: give another "
                           "--dest, or --force to replace them")
    dest.mkdir(parents=True, exist_ok=True)
    for p in sources:
        shutil.copyfile(p, dest / p.name)
        print(f"wrote {dest / p.name}")
    return 0


def _cmd_validate(args: argparse.Namespace) -> int:
    from .fmu.validate import validate_files

    try:
        return validate_files(args.fmu, dy=args.dy, dx=args.dx)
    except ValueError as exc:  # the band: one line, exit 2
        raise GyroFmuError(str(exc)) from None


def _cmd_doctor(args: argparse.Namespace) -> int:
    from .doctor.report import main as doctor_main

    return doctor_main(Path(args.fmu) if args.fmu else None, compile_host=not args.no_compile)



#: The subcommands as a user thinks of them; `gyro-fmu --help` lists them so.
GROUPS = {
    "simulate": ("run", "report", "sweep"),
    "analyse": ("observability", "identify", "design-drive", "spec", "datasheet"),
    "calibrate": ("selfcal", "selfcal-warmup", "selfcal-lot", "ratetable"),
    "export": ("build", "fmus", "ssp", "container", "examples"),
    "check": ("validate", "doctor"),
}


class DefaultsFormatter(argparse.HelpFormatter):
    """Help that prints each option's default from the code ("(default: X)"), so that
    no help string types it again; options whose default is None (decided where the
    value is used) or a flag's False say nothing."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if ("%(default)" in text or action.default in (None, False, argparse.SUPPRESS)
                or not action.option_strings):
            return text
        return f"{text} (default: %(default)s)"


def parser() -> argparse.ArgumentParser:
    from .fmu.build import FMU_NAMES, MODELS_DIR

    p = argparse.ArgumentParser(
        prog="gyro-fmu",
        description="MEMS gyroscope FMUs (US 2011/0314910 A1) and their self-calibration "
                    "(US 9,482,553): build, co-simulate, calibrate, report.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    p.add_argument("--debug", action="store_true",
                   help="show the traceback of an error instead of one line")
    p.add_argument(*QUIET, action="store_true",
                   help="say nothing while working: warnings and errors only (stderr)")
    p.add_argument(*VERBOSE, action="store_true",
                   help="say more while working: debug lines (every FMU log message)")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND",
                           parser_class=_SubcommandParser)

    b = sub.add_parser("build", help=f"build {', '.join(FMU_NAMES)} into models/")
    b.add_argument("--dest", default=str(MODELS_DIR),
                   help="output folder, under the working directory")
    b.add_argument("--flavour", choices=("native", "pythonfmu"), default="native",
                   help="native: the package's C FMUs; pythonfmu: pythonfmu "
                   "adapters over the same C core instead (they need this Python; "
                   "GyroSensor has none)")
    b.set_defaults(func=_cmd_build)

    f = sub.add_parser("fmus", help=f"copy the native FMUs ({', '.join(FMU_NAMES)}; every "
                       "platform, FMI 2.0 and 3.0) out for your own tool")
    f.add_argument("--dest", default="fmus", help="output folder")
    f.add_argument("--fmi", choices=("2", "3", "both"), default="both",
                   help="FMI version (both: into DEST/fmi2 and DEST/fmi3)")
    f.set_defaults(func=_cmd_fmus)

    e = sub.add_parser("examples", help="copy the example scripts the tutorials run "
                       "(python DEST/NAME.py) into a folder")
    e.add_argument("--dest", default="examples", help="output folder")
    e.add_argument("--force", action="store_true",
                   help="replace files of the same names that differ")
    e.set_defaults(func=_cmd_examples)

    v = sub.add_parser("validate", help="re-simulate FMUs and compare with the reference "
                       "results they carry (fmi-ls-ref); exit 1 on any difference")
    v.add_argument("fmu", nargs="+", help="FMU file(s)")
    v.add_argument("--dy", type=options.band,
                   default=1e-6,
                   help="band half-width as a fraction of each signal's range")
    v.add_argument("--dx", type=options.count, default=1,
                   help="band width in samples")
    v.set_defaults(func=_cmd_validate)

    d = sub.add_parser("doctor", help="what OMSimulator/Simulink/Dymola/C hosts need to load "
                       "the FMUs, checked with a compiled C host")
    d.add_argument("--fmu", help="FMU to load in the check (default models/GyroPlant.fmu)")
    d.add_argument("--no-compile", action="store_true",
                   help="print the settings only, skip the C-host check")
    d.set_defaults(func=_cmd_doctor)

    from .selfcal.cli import register as register_selfcal
    from .spec.cli import register as register_spec
    from .spec.datasheet_cli import register as register_datasheet
    from .system.cli import register as register_system

    register_system(sub)
    register_selfcal(sub)
    register_spec(sub)
    register_datasheet(sub)
    p.epilog = _grouped(sub)
    return p


class _SubcommandParser(argparse.ArgumentParser):
    """A subcommand: its help line is its description too, its defaults are printed."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        kwargs.setdefault("formatter_class", DefaultsFormatter)
        super().__init__(*args, **kwargs)


def _grouped(sub: argparse._SubParsersAction) -> str:
    """The commands by group, one line each (their help), and each subparser's
    description set from that help where it has none."""
    helps = {a.dest: a.help or "" for a in sub._choices_actions}
    listed = [name for names in GROUPS.values() for name in names]
    missing = sorted(set(sub.choices) - set(listed))
    if missing:  # a command nobody put in a group: a bug (tests/test_cli.py)
        raise RuntimeError(f"gyro-fmu commands in no group: {missing}")
    sub._choices_actions.clear()  # listed by group below instead of in one flat list
    sub.help = "one of the commands below"
    lines = ["commands (gyro-fmu COMMAND --help for each):"]
    for group, names in GROUPS.items():
        lines.append(f"  {group}:")
        for name in names:
            lines += textwrap.wrap(helps[name], 88, initial_indent=f"    {name:<15} ",
                                   subsequent_indent=" " * 20)
            if sub.choices[name].description is None:
                sub.choices[name].description = helps[name][:1].upper() + helps[name][1:] + "."
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run one command. Exit codes: 0 done, 1 a check failed (validate, identify, a sweep
    with failed gyros), 2 an
    input, file or FMU that cannot be used (GyroFmuError) or an OS error (a folder that
    cannot be written, a file that is not there): one line naming the cause and the
    remedy, no traceback unless --debug; 130 Ctrl-C, after the work so far is written."""
    argv = list(sys.argv[1:] if argv is None else argv)
    # anywhere on the line, before or after the command
    debug = "--debug" in argv
    verbosity = ((any(a in VERBOSE for a in argv) and 1)
                 or (-1 if any(a in QUIET for a in argv) else 0))
    _terminate_as_interrupt()
    try:  # the imports behind the parser take a second: Ctrl-C there is an interrupt too
        try:  # argparse's own refusal (an option's type, --help, --version): its code
            args = parser().parse_args([a for a in argv
                                        if a not in ("--debug", *QUIET, *VERBOSE)])
        except SystemExit as exc:
            return exc.code if isinstance(exc.code, int) else 2
        from .model.parameters import UnstablePlantWarning

        with warnings.catch_warnings(), command_logging(verbosity):
            warnings.simplefilter("ignore", UnstablePlantWarning)  # reported via summary
            return args.func(args)
    except KeyboardInterrupt as exc:
        if debug:
            raise
        print(f"gyro-fmu: interrupted{f': {exc}' if str(exc) else ''}", file=sys.stderr)
        return 130
    except (GyroFmuError, OSError) as exc:
        if debug:
            raise
        print(f"gyro-fmu: error: {error_line(exc)}", file=sys.stderr)
        return 2


def _terminate(signum: int, frame: object) -> None:
    raise KeyboardInterrupt("terminated (SIGTERM)")


def _terminate_as_interrupt() -> None:
    """SIGTERM (kill, a CI timeout, a job scheduler) is handled as Ctrl-C: the work so far
    is written and the unpacked FMU folders are removed (the default would end the process
    with nothing cleaned up)."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminate)


def error_line(exc: BaseException) -> str:
    """The message of a GyroFmuError as is; an OS error with its file and a remedy."""
    if not isinstance(exc, OSError) or isinstance(exc, GyroFmuError):
        return str(exc)
    where = f"{exc.filename}: " if exc.filename else ""
    what = exc.strerror or str(exc)
    if isinstance(exc, FileNotFoundError):
        remedy = "check the path (a missing folder on the way?)"
    elif isinstance(exc, (PermissionError, IsADirectoryError, NotADirectoryError,
                          FileExistsError)):
        remedy = "give a path you may write and that is not in the way of a file or folder"
    else:
        remedy = "check the path, the free space and the permissions"
    return f"{where}{what}: {remedy} (--debug shows the traceback)"


if __name__ == "__main__":
    raise SystemExit(main())
