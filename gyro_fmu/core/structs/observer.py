"""The observer's structs (US 2011/0314910 A1, eqs. 5-9; fmu_src/core/gyro_observer.h): its
tuning (the FMU parameters GyroObserver and GyroSensor declare from it), the divergence
monitor, the re-fit test, the held step's reusable maps and the whole filter."""

from __future__ import annotations

from .base import Constant, Field, Struct

NPAR = Constant("GYRO_OBS_NPAR", 7, "kxx, kyy, kxy, dxx, dyy, dxy, b = 1/m")
NMAX = Constant("GYRO_OBS_NMAX", 14, "most filter states (rate block of 3)")
MMAX = Constant("GYRO_OBS_MMAX", 7, "most rate models (the adaptive set)")
RMAX = Constant("GYRO_OBS_RMAX", 3, "most rate-block states")
MESSAGE = Constant("GYRO_OBS_MESSAGE", 1024, "bytes of the observer's messages")

TUNING = Struct("GyroObserverTuning", "The observer's tuning (ObserverTuning in Python; the "
                "defaults need no knowledge of the rate or the noise).", (
    Field('noise_rel', default=1e-06, unit='1', min=0.0,
          doc=('floor of the measurement noise std relative to the running peak of each measured '
               'signal (where sigma_z1, sigma_z2 are 0: the observer then estimates the noise '
               'from its innovations, above this floor; 1e-6 suits noise-free data)')),
    Field('sigma_z1', default=0.0, unit='m', min=0.0,
          doc=('absolute measurement noise std of z1 (x; in m/s for vx when measured_pair = 2); '
               '> 0 overrides the estimated noise')),
    Field('sigma_z2', default=0.0, unit='m', min=0.0,
          doc=('absolute measurement noise std of z2 (y; in m/s for vy when measured_pair = 2); '
               '> 0 overrides the estimated noise')),
    Field('innov_floor', default=1.0, unit='1', min=0.0,
          doc=('noise estimated from the innovations (sigma_z 0): the noise variance is at least '
               'innov_floor times the running mean of the squared innovations (1: covariance '
               'matching)')),
    Field('innov_tau', default=0.001, unit='s', min=0.0,
          doc=('time constant of the running mean of the squared innovations')),
    Field('rate_model', 'int32_t', default=0, unit='1', min=0.0, max=4,
          doc=('model of Omega_z(t): 0 adaptive (the observer finds from its innovations whether '
               'the rate is constant, wandering, slow or agile: an interacting-multiple-model '
               'filter, docs/observer-rate-model.md); 1 constant; 2 tracking (follows rate_span '
               'at rate_bandwidth); 3 expert (q_Omega on the omega_order-th derivative); 4 '
               'adaptive with a moving bank (the wandering and slow models follow the '
               "likelihood down to small slow motions, and restarts more after steps from "
               'rest: docs/observer-rate-model.md)')),
    Field("pad_rate_model", "int32_t", hidden=True),  # the doubles stay 8-byte aligned
    Field('rate_bandwidth', default=150.0, unit='Hz', min=0.0,
          doc=('fastest rate motion to follow (rate_model 0 and 2): the agile model follows a '
               'sine of amplitude rate_span at this frequency, the slow and rough models at a '
               'tenth')),
    Field('rate_span', default=1.0, unit='rad/s', min=0.0,
          doc=('amplitude of the rate motion to follow at rate_bandwidth (rate_model 0 and 2)')),
    Field('rate_dwell', default=100.0, unit='s', min=0.0,
          doc=('rate_model 0: mean time the rate keeps one behaviour (constant, rough, slow, '
               'agile) before it may switch')),
    Field('q_Omega', default=1000000000.0, unit='rad2/s5', min=0.0,
          doc=('rate_model 3 only: spectral density of the white noise driving the '
               'omega_order-th derivative of Omega_z (unit for omega_order 2; rad2/s3 for 1, '
               'rad2/s7 for 3)')),
    Field('omega_order', 'int32_t', default=2, unit='1', min=1, max=3,
          doc=('rate_model 3 only: 1 random walk, 2 integrated random walk, 3 twice integrated '
               'random walk')),
    Field("pad_omega_order", "int32_t", hidden=True),
    Field('q_param_rel', default=0.0, unit='1/s', min=0.0,
          doc=('random-walk spectral density of the relative parameter deviations (0: constant '
               'parameters)')),
    Field('sigma0_k_rel', default=0.1, unit='1', min=0.0,
          doc=('initial 1-sigma of kxx, kyy, kxy relative to their initial guesses')),
    Field('sigma0_d_rel', default=0.5, unit='1', min=0.0,
          doc=('initial 1-sigma of dxx, dyy, dxy relative to the largest |d| guessed')),
    Field('sigma0_m_rel', default=0.1, unit='1', min=0.0,
          doc=('initial 1-sigma of m relative to its initial guess')),
    Field('sigma0_Omega', default=2.0, unit='rad/s', min=0.0,
          doc=('initial 1-sigma of Omega_z')),
    Field('sigma0_Omega_rate', default=1000.0, unit='rad/s2', min=0.0,
          doc=('initial 1-sigma of dOmega_z/dt (omega_order 2 and 3)')),
    Field('sigma0_Omega_acc', default=1000000.0, unit='rad/s3', min=0.0,
          doc=('initial 1-sigma of d2Omega_z/dt2 (omega_order 3)')),
    Field('sigma0_position', default=0.0, unit='m', min=0.0,
          doc=('initial 1-sigma of x and y; 0: scaled to the signal (the state is taken at rest '
               'until the first drive or measurement above its noise, then known to 1 % of the '
               "drive's static deflection, or to the size of that measurement)")),
    Field('sigma0_velocity', default=0.0, unit='m/s', min=0.0,
          doc=('initial 1-sigma of vx and vy; 0: scaled to the signal like sigma0_position '
               '(times the guessed natural frequency)')),
    Field('joseph', 'int32_t', default=True, unit='1', min=0.0, max=1, pytype=bool,
          doc=('1: Joseph-form covariance update, symmetrized (keeps the covariance positive '
               'definite; docs/observer-soundness.md); 0: P - K H P (loses it at some steps)')),
    Field("reserved", "int32_t", hidden=True),
))

MONITOR_LIMITS = Struct(
    "GyroMonitorLimits", "Limits of the divergence monitor (gyro_observer_init sets them; "
    "observer_monitor.py says why each is what it is).", (
        Field("block", "int32_t",
              doc="innovation statistics judged over blocks of this many corrections"),
        Field("absolute", "int32_t", doc="absolute noise stds given: NIS against chi-square"),
        Field("nis_warn", doc="block mean NIS (2 dof per correction)"), Field("nis_lost"),
        Field("rel_warn", doc="relative mode: block RMS innovation / running peak"),
        Field("rel_lost"),
        Field("ratio", doc="kxx, kyy, 1/m within [theta0 / ratio, theta0 ratio]"),
        Field("d_max", unit="1/s", doc="|dxx|, |dyy|, |dxy| <= d_max"),
        Field("omega_max", unit="rad/s", doc="|Omega_z| <= omega_max"),
        Field("corr_warn", doc="warning: lag-1 autocorrelation above corr_warn ..."),
        Field("nis_min", doc="... while NIS above nis_min")))

MONITOR = Struct("GyroMonitor", "The monitor's accumulators over the current block and its "
                 "last verdict.", (
    Field("nis", doc="sum of NIS in the block so far"),
    Field("count", doc="corrections in the block so far"),
    Field("status", doc="last verdict (GYRO_MON_*)"), Field("cause"),
    Field("which", doc="what tripped it"), Field("value", doc="the value that tripped it"),
    Field("block", doc="blocks judged"),
    Field("last_nis", doc="the last block's mean NIS"),
    Field("last_rel", doc="the last block's RMS innovation / peak"),
    Field("prev", shape=(2,), doc="last innovations (z1, z2)"),
    Field("ac", shape=(2,), doc="lag-1 products"), Field("sq", shape=(2,), doc="squares"),
    Field("last_corr", doc="the last block's larger lag-1 autocorrelation")))

REFIT = Struct(
    "GyroRefit", "The re-fit test: does a re-fit of the last ~tau of data move the estimate? "
    "With the parameters and Omega_z held at the estimate, W = d[x, vx/wx, y, vy/wy]^- / "
    "d(p, Omega_z) is the predicted plant state's sensitivity (W <- Phi (I - K H) W + S each "
    "step, K the state rows of the combined gain); psi = H W is that of the innovations nu. "
    "The score g = sum lambda^(N-k) psi' S^-1 nu and its covariance F = sum lambda^(2(N-k)) "
    "psi' S^-1 psi (lambda = exp(-h / tau)) give T = g' F^-1 g, chi-square with 8 dof while "
    "the estimate fits the window: the drop in chi-square a Gauss-Newton re-fit of the "
    "window would gain (docs/observer-soundness.md).", (
        Field("W", shape=(4, 8)), Field("g", shape=(8,)), Field("F", shape=(8, 8)),
        Field("weight", doc="sum of lambda^(2(N-k)) so far: the window is judged once full"),
        Field("last_T", doc="T at the last block judged (-1: not judged yet)"),
        Field("shift", shape=(8,),
              doc="the re-fit's move of (p, Omega_z) at the last block, in sigmas"),
        Field("move", shape=(8,), doc="... in the filter's units"),
        Field("restarts", doc="re-fits that rejected the estimate (each re-opened P along move)"),
        Field("pending", doc="1: the last judged window rejected the estimate; the next "
              "judges")))

HELD = Struct(
    "GyroObsHeld", "The held step's maps at one linearization point xc (the scaled parameters "
    "and Omega_z, filter rows IPAR..IOM) and step h, reused while the filter's point stays "
    "near xc (gyro_observer_held.c). Every map is linear in [s, ux, uy]: s1 = Phi s + psi u "
    "and S = sum_k s_k Sk[k] + ux Sk[4] + uy Sk[5], and Sk[k][i][q] = dPhi[i][k]/dx_q, so a "
    "move dx from xc is corrected to first order.", (
        Field("valid", doc="1: the maps hold at (xc, h)"),
        Field("h", unit="s", doc="the step they were built for"),
        Field("xc", shape=(8,), doc="where they were built (or, not valid yet, where "
              "steadiness began)"),
        Field("steady", doc="consecutive linearizations within tol of xc"),
        Field("tol", doc="reuse while ||dA_aug h||_inf <= tol (0: never reuse)"),
        Field("reused", doc="linearizations from the maps (statistics)"),
        Field("built", doc="builds of them (statistics)"),
        Field("norm", shape=(8,), doc="||dA_aug/dx_q h||_inf without the force's part"),
        Field("Phi", shape=(4, 4)), Field("psi", shape=(2, 4), doc="s1 per unit ux, uy"),
        Field("Sk", shape=(6, 4, 8), doc="S per unit s_0..s_3, ux, uy")))

WANDER = Struct(
    "GyroWander", "rate_model 0's constant model, tested for consistency along Omega_z at "
    "two time scales (WANDER_BLOCK): over each block its own corrections of Omega_z sum to "
    "C, its variance drops sum to V; a consistent filter has E[C^2] = V (its corrections "
    "are a martingale's increments). r = C^2 / V moves log q of that scale (not up in a "
    "block where the model lost the probability: a jump); the model is a random walk of "
    "the sum of the two q (each 0 at its floor): a rate that wanders more slowly than the "
    "rough models is covered (docs/observer-rate-model.md).", (
        Field("log_q", shape=(2,), doc="log of each scale's intensity over the rough model's"),
        Field("C", shape=(2,), unit="rad/s", doc="this block's sum of the model's Omega_z "
              "corrections"),
        Field("V", shape=(2,), unit="rad^2/s^2", doc="... of its Omega_z variance drops"),
        Field("time", shape=(2,), unit="s", doc="this block's length so far"),
        Field("mu_min", shape=(2,), doc="the constant model's least probability in the block"),
        Field("r", shape=(2,), doc="EWMA of C^2 / V over blocks (a diagnostic)")))

_I = "int32_t"
OBSERVER = Struct(
    "GyroObserver", "What one observer is: constants of its scaling, the rate models of the "
    "current step and its state. A plain struct (no pointers): an FMU state is a copy of it.", (
        Field("tuning", TUNING),
        Field("pair", _I, doc="1: positions x, y measured; 2: velocities vx, vy"),
        Field("n", _I, doc="filter states: 4 + 7 + order"),
        Field("order", _I, doc="rate-block states"),
        Field("n_models", _I, doc="rate models run (GYRO_OBS_MMAX adaptive, else 1)"),
        Field("i0", _I, doc="filter-state row of z1 (z2 is row i0 + 2)"),
        Field("auto_prior", _I, doc="the prior of [x, vx, y, vy] waits for the first signal"),
        Field("status", _I, doc="0 ok, 1 warning, 2 lost"),
        Field("lost", _I, doc="1: lost (message in lost_message); every step refuses"),
        Field("P_partial", _I, doc="1: P holds only its diagonal and the measured rows' "
              "columns (gyro_observer_complete_covariance fills the rest)"),
        Field("theta0", shape=(NPAR,)), Field("scale", shape=(NPAR,)),
        Field("wx", unit="rad/s", doc="sqrt(kxx_0)"), Field("wy", unit="rad/s",
                                                             doc="sqrt(kyy_0)"),
        Field("hgain", shape=(2,), doc="z = hgain * (x[i0], x[i0 + 2]): [1, 1] or [wx, wy]"),
        Field("MgT", shape=(5, 16), doc="d(A_aug xi)/d(p, Omega_z), rows 1 and 3"),
        Field("lim", MONITOR_LIMITS),
        Field("h_cached", unit="s", doc="the step the rate models below are for"),
        Field("qpar"),
        Field("rate_scale", doc="rate_model 4: log of the moving bank's scale c (its rough "
              "models at c x {1/10, 1, 10} of the rough intensity, the slow one at min(c, 1))"),
        Field("wander", WANDER),
        Field("Fr", shape=(MMAX, RMAX, RMAX)), Field("Qr", shape=(MMAX, RMAX, RMAX)),
        Field("Pi", shape=(MMAX, MMAX), doc="rate models' transition probabilities"),
        Field("x", shape=(NMAX,), doc="the combined estimate"),
        Field("P", shape=(NMAX, NMAX)),
        Field("xs", shape=(MMAX, NMAX), doc="each rate model's filter"),
        Field("Ps", shape=(MMAX, NMAX, NMAX)),
        Field("mu", shape=(MMAX,), doc="model probabilities after the last correction"),
        Field("c", shape=(MMAX,), doc="... predicted to the next one"),
        Field("peak", shape=(2,), doc="running peak |z1|, |z2|"),
        Field("nu2", shape=(2,), doc="EWMA of squared innovations (< 0: not started)"),
        Field("nu2_zero", shape=(2,), doc="the same EWMA started from 0 (its mean: divided "
              "by nu2_mass), for the covariance's noise"),
        Field("nu2_mass", doc="the total weight nu2_zero has taken in, 1 - prod(1 - w)"),
        Field("mon", MONITOR), Field("refit", REFIT),
        Field("t", unit="s", doc="since construction"),
        Field("held", HELD, doc="the held step's reusable maps (a cache: reset on restore)"),
        Field("lost_message", "char", shape=(MESSAGE,))))

CONSTANTS = (NPAR, NMAX, MMAX, RMAX, MESSAGE)
STRUCTS = (TUNING, MONITOR_LIMITS, MONITOR, REFIT, HELD, WANDER, OBSERVER)
