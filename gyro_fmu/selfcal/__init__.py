"""Self-calibration without rotation (US 9,482,553): the closed-loop gyroscope.

Architecture, one job per module:

- `resonator`: the electrostatic ring/MEMS resonator of the seed's eq. 1 (voltages
  in, pick-off voltages out), stepped exactly with held inputs;
- `loops`: the electronics (PLL, amplitude control, force rebalance, sideband
  modulation, mode reversal, off-resonant excitation), one sample at a time;
- `carrier`: resonator + loops at carrier rate, in process, in the same Jacobi
  order as the FMUs (GyroResonator.fmu, GyroLoops.fmu) run through the fmpy master;
- `phasors`: least-squares phasors at known frequencies (demodulation);
- `estimator`: sideband transfer functions, the fit of eq. 19, bias and scale factor;
- `sequence`: the calibration flow of the seed (feed-forward, pick-off phase, two
  modes, estimation); `ratetable`: the conventional calibration it must reproduce.
"""
