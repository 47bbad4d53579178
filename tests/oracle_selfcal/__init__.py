"""gyro_fmu 0.3.0's self-calibration resonator, loops and fused carrier run (numba
kernels, scipy's expm, numpy's PCG64 noise), frozen as the oracle of their C port.

Copied from gyro_fmu/selfcal/{resonator,loops,inprocess,noise}.py at 0.3.0 with only the
imports pointing here. The loops compare bit for bit with the core; the resonator's step
matrices come from another matrix exponential (the core's Pade 13, scipy's Al-Mohy and
Higham), and its noise from the core's generator, so noise-free runs compare within a
stated tolerance and noisy ones statistically. Needs numba (the test extra).
"""
