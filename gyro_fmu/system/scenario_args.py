"""The scenario a command line describes: the options every scenario command shares
(--scenario, --preset, --set, --rate, --drive, ...) turned into a Scenario. Used by
`gyro-fmu run`, `sweep` and the other scenario commands (system/cli.py, sweep_cli.py)."""

from __future__ import annotations

import argparse
from dataclasses import fields, replace

from ..model.parameters import ParameterError
from ..model.rate import RateProfile
from .scenario import Scenario, scenario

#: s, each gyro's run of a sweep when --stop-time is not given (a run's own default is
#: longer)
SWEEP_STOP_TIME = 0.08


def scenario_from_args(args: argparse.Namespace) -> Scenario:
    base = scenario(args.scenario)
    changes: dict[str, object] = {}
    if args.preset is not None:
        changes["preset"] = args.preset
    if args.set:
        changes["overrides"] = {**base.overrides, **dict(args.set)}
    if args.rate is not None:
        try:
            changes["rate"] = RateProfile.parse(args.rate)
        except ValueError as exc:
            raise ParameterError(str(exc)) from None
    if args.drive is not None:
        from ..model.drive import TwoToneDrive

        values = dict(args.drive)
        known = [f.name for f in fields(TwoToneDrive)]
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise ParameterError(f"unknown --drive name(s) {unknown}: the names are {known}")
        changes["drive"] = replace(base.the_drive, **values)
    for name in ("stop_time", "step", "noise", "seed", "measured_pair", "Omega_z_0"):
        value = getattr(args, name)
        if value is not None:
            changes[name] = value
    if args.initial:
        changes["initial"] = dict(args.initial)
    if args.tuning:
        changes["tuning"] = dict(args.tuning)
    return base.with_(**changes)
