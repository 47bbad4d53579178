"""Electronics and records designed around the resonator.

The seed designs its loops around the instrument; so does `loops_for`: from the
resonator's *nominal* frequency f, quality factor Q and forcer-to-pick-off gain
c = Px Bx / (2 omega) (the envelope's response to a drive voltage, 1/s) it derives

- the NCO centre f and the nominal Q and c the gains are computed from
  (LoopSettings.as_array turns bandwidths into gains through c);
- bandwidths and demodulator cut-offs in proportion to f: PLL f/200, rebalance f/40,
  3 low-pass sections at f/8 (PLL, AGC), 2 at f/2 (rebalance); 20, 100, 500 and
  2000 Hz at 4 kHz. The AGC stays at 3 Hz: it must pass the sideband tones
  (0.2-1.4 Hz), whatever the carrier;
- the amplitude setpoint: 1 V, or less when holding it would take more than 40 % of
  the drive limit (the drive holding amplitude A is A / (c tau), tau = Q / (pi f));
  the rest is headroom for the sidebands and the AGC.

`spacing_for` spaces the sideband tones by 3/4 of the mode's half-power half-width
f / (2 Q), never below 0.2 Hz (the seed's default, two Hann bins of a 10 s record)
nor above 2 Hz: on a 15 kHz, Q 5.7e3 resonator (half-width 1.3 Hz) 1 Hz instead of
0.2 Hz halved the bias 1-sigma of a 10 s record (1.2e-4 -> 6.8e-5 rad/s; 2 Hz: 9.5e-5).
`step_for` gives 10 samples per carrier cycle on a grid that makes every whole
second a whole number of steps. `design` puts both into a SelfCalConfig; `--loop
NAME=VALUE` (gyro-fmu selfcal) and the GyroLoops.fmu parameters override any of them.
The nominal values are what the engineer knows of the instrument (its datasheet);
the lot study designs from the lot's nominal and calibrates resonators drawn around it.
"""

from __future__ import annotations

import math
from dataclasses import fields, replace

from ..model.loops import LoopSettings
from ..model.resonator import ResonatorParameters

#: Fraction of the drive limit the amplitude control may need to hold its setpoint.
DRIVE_HEADROOM = 0.4
#: Samples per carrier cycle.
SAMPLES_PER_CYCLE = 10
LOOP_NAMES = tuple(f.name for f in fields(LoopSettings))
#: The settings a user may override (the sequence sets the mode, the sidebands and
#: the measured feed-forward itself).
USER_LOOPS = tuple(n for n in LOOP_NAMES
                   if n != "mode" and not n.startswith(("sideband_", "ff_")))


def plant_gain(res: ResonatorParameters) -> float:
    """c = Px Bx / (2 omega_x), 1/s: pick-off volts per second of envelope growth per
    drive volt (the envelope of a resonance responds to a force F as F / (2 omega))."""
    return res.Px * res.Bx / (2.0 * res.omega_x)


def loops_for(nominal: ResonatorParameters, **overrides: float) -> LoopSettings:
    """LoopSettings designed for the nominal resonator; overrides win (LoopSettings
    field names). Unknown names are refused by name."""
    unknown = sorted(set(overrides) - set(LOOP_NAMES))
    if unknown:
        from ..model.loops import LoopsError

        raise LoopsError(f"unknown loop setting(s) {', '.join(unknown)}; "
                         f"known: {', '.join(LOOP_NAMES)}")
    f, q, c = nominal.f_x, nominal.Q_x, plant_gain(nominal)
    base = LoopSettings()
    tau = q / (math.pi * f)
    limit = overrides.get("drive_limit", base.drive_limit)
    amplitude = min(1.0, DRIVE_HEADROOM * limit * c * tau)
    designed = {
        "f_nominal": f, "q_nominal": q, "plant_gain": c, "amplitude": amplitude,
        "pll_bandwidth": f / 200.0, "rebalance_bandwidth": f / 40.0,
        "demod_cutoff": f / 8.0, "rebalance_cutoff": f / 2.0,
    }
    return replace(base, **{**designed, **overrides})


def step_for(f_nominal: float) -> float:
    """About SAMPLES_PER_CYCLE samples per cycle, 1 / step a whole number of Hz (25 us
    at 4 kHz)."""
    return 1.0 / (SAMPLES_PER_CYCLE * max(1, round(f_nominal)))


def spacing_for(f_nominal: float, q_nominal: float) -> float:
    """Hz between sideband tones: 0.75 f / (2 Q), within [0.2, 2] Hz, on a 0.1 Hz grid
    (so that 10 s records hold whole periods)."""
    return min(2.0, max(0.2, round(0.75 * f_nominal / (2.0 * q_nominal), 1)))


def design(nominal: ResonatorParameters, loops: dict[str, float] | None = None,
           **config: object) -> object:
    """SelfCalConfig for the nominal resonator: its step and loops (overrides in
    `loops`), the other fields from `config`."""
    from .sequence import SelfCalConfig

    lo = loops_for(nominal, **(loops or {}))
    config.setdefault("step", step_for(lo.f_nominal))
    config.setdefault("sideband_spacing", spacing_for(lo.f_nominal, lo.q_nominal))
    return SelfCalConfig(loops=lo, **config)
