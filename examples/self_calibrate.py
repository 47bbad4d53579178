"""Self-calibration of bias and scale factor without rotation (US 9,482,553) on a
resonator that is no preset, checked against a rate table of the same gyro.

    python examples/self_calibrate.py

self_calibrate runs the whole sequence (loops off for the feed-forward, both modes with
sidebands, the eq. 19 fit) and refuses, naming the cause, a calibration it cannot trust
(CalibrationRefusedError). The loops and the step are designed from the nominal values.
"""

from __future__ import annotations

from dataclasses import replace

from gyro_fmu.model.resonator import ResonatorParameters
from gyro_fmu.selfcal.alarms import CalibrationRefusedError
from gyro_fmu.selfcal.design import design
from gyro_fmu.selfcal.ratetable import table_at_readout
from gyro_fmu.selfcal.sequence import self_calibrate


def main() -> int:
    nominal = replace(ResonatorParameters(), f_x=7000.0, f_y=7000.0, Q_x=5e4, Q_y=5e4,
                      Bx=0.15, By=0.15)
    # the instrument: split 0.4 Hz, Q mismatch, cross damping and stiffness, pick-off noise
    instrument = replace(nominal, f_y=7000.4, Q_y=4.6e4, dxy=3e-3, kxy=5e3, noise=2.5e-4)
    cfg = design(nominal)
    try:
        result = self_calibrate(instrument, cfg)
    except CalibrationRefusedError as refused:
        print("refused:", "; ".join(refused.problems))
        return 2
    table = table_at_readout(instrument, result, cfg)
    d_bias = result.bias - table.bias
    d_sf = (result.scale_factor / table.scale_factor - 1) * 1e6
    print(f"bias {result.bias:+.5e} rad/s (1-sigma {result.sigma_bias:.1e}), "
          f"{d_bias:+.1e} off the rate table")
    print(f"scale factor {result.scale_factor:.6f} V/(rad/s) (1-sigma "
          f"{result.sigma_sf_ppm:.1f} ppm), {d_sf:+.1f} ppm off the rate table")
    print(f"{result.record:g} s records, sideband index {result.sideband_index:.3g}, "
          f"misfit {result.misfit_ratio:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
