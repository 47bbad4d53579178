"""gyro_fmu 0.3.0's GyroStateObserver (numba kernels), frozen as the oracle of its C port.

Copied from gyro_fmu/estimation/observer*.py and model/dynamics.py at 0.3.0; the imports
point here, and one change: the split held step (||A h|| > 0.5, in sub-steps) chained its
Jacobians with numpy's matrix product (BLAS, which reorders and may fuse), written here
as the loops the C core runs. With numpy's product the outputs differ from the core's by
up to 7e-9 relative on 19 of 20 random gyros with coarse steps (measured); with the loops,
by nothing. The core keeps the rest of the operation order, so the tests compare bit for
bit. Needs numba (the test extra).

Since 0.3.0 the C core has changed the adaptive rate model's set, and the oracle follows:
three more rough models at 3, 10 and 100 times the rough model's intensity
(observer_rate.ROUGH_GRADES; their probabilities count as "rough"). The re-fit test of the
core changes only the status, once its 20 ms window is full: the oracle's cases are
shorter.
"""
