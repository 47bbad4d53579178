/*
 * loader.c - a small FMI 2.0 co-simulation loader that takes the place of
 * pythonfmu's binaries/linux64/<modelIdentifier>.so, so that a non-Python host
 * (a C program, OMSimulator, the ecos CLI) can load a pythonfmu FMU with no
 * LD_PRELOAD / PYTHONHOME / PYTHONPATH on the machine that built it.
 *
 * pythonfmu's real binary (libpythonfmu-export.so) is kept next to this one as
 * <modelIdentifier>_pythonfmu.so. On first use this loader
 *
 *   1. finds its own file (dladdr), the FMU root (three levels up) and reads
 *      resources/python_env.txt (written by gyro_fmu/pythonfmu/loader.py from the Python
 *      that built the FMU): libpython path, PYTHONHOME, PYTHONPATH entries,
 *      Python version, the offset of pythonfmu's pyState shared_ptr;
 *   2. if Python is not already in the process (dlsym(RTLD_DEFAULT,
 *      "Py_IsInitialized")), dlopen's libpython RTLD_NOW|RTLD_GLOBAL
 *      (PYTHONFMU_LIBPYTHON overrides the file); if the interpreter is not
 *      initialized yet, sets PYTHONHOME (unless the user set it) and prepends
 *      the PYTHONPATH entries that are not there yet, after checking that the
 *      home holds lib/pythonX.Y/os.py (else Py_Initialize would abort the host);
 *   3. dlopen's the real binary (RTLD_NOW|RTLD_LOCAL) and forwards every FMI
 *      2.0 co-simulation function to it.
 *
 * When something is missing, fmi2Instantiate reports what it looked for and how
 * to fix it through the host's logger (fmi2Error, "logStatusError") and returns
 * NULL. fmi2GetTypesPlatform/fmi2GetVersion answer the standard constants
 * without loading anything (they are fixed by the standard and may be called
 * before fmi2Instantiate, also when Python is missing).
 *
 * Exit-time fix: pythonfmu 0.7.0 frees its interpreter guard twice at process
 * exit; gyro_fmu/pythonfmu/upstream_exit.py defuses it on the real binary (which the
 * slave finds as <modelIdentifier>_pythonfmu.so). The real binary is never
 * dlclose'd, since dlclose of it runs exactly that use after free.
 *
 * Status the slave cannot deliver through pythonfmu (which knows only fmi2OK and
 * fmi2Discard, and answers fmi2Terminated = true after any fmi2Discard, so
 * fmpy.simulate_fmu silently ended a run at a recoverable refusal): every instance
 * is wrapped in a `struct instance`; while a call runs, the slave (through
 * ctypes, gyro_fmu/fmu/host_status.py) may call pythonfmu_shim_report() to raise
 * the status of that call (fmi2Warning, fmi2Error) and to say whether it can no
 * longer step. fmi2GetBooleanStatus(fmi2Terminated) is answered here: false while
 * the slave can step; fmi2Error with the reason logged once it cannot, so a host
 * such as fmpy raises instead of ending the run as if it were complete.
 *
 * The loader's own log messages are formatted here and passed without arguments (every
 * '%' doubled), so a host whose logger reads only the message (a ctypes callback, such
 * as gyro_fmu's co-simulation master) gets the text, not "%s ... %s".
 *
 * Environment: PYTHONFMU_LIBPYTHON (libpython to load), PYTHONHOME (kept if
 * set), PYTHONPATH (ours are prepended), PYTHONFMU_SHIM_VERBOSE=1 (trace on
 * stderr).
 *
 * Build: cc -shared -fPIC -O2 -fvisibility=hidden -U_FORTIFY_SOURCE -Iinclude \
 *           -o shim.so python_loader.c python_loader_env.c \
 *           -Wl,--no-as-needed -l:libdl.so.2
 * Only GLIBC_2.2.5 symbols are referenced (see the .symver lines below), so the
 * loader itself loads on any x86_64 glibc and can report a too-old glibc for
 * the real binary (which needs GLIBC_2.32 and GLIBCXX_3.4.30) instead of the
 * host failing at dlopen.
 */
#define _GNU_SOURCE
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "python_loader.h"

/* Marker that gyro_fmu/pythonfmu/loader.py looks for to recognise an installed loader. */
__attribute__((used)) static const char shim_marker[] = "@(#)" SHIM_VERSION;

/* ------------------------------------------------------------------------ */
/* The FMI 2.0 co-simulation functions                                      */
/* ------------------------------------------------------------------------ */
FMI2_Export const char *fmi2GetTypesPlatform(void)
{
    return loaded ? real.fmi2GetTypesPlatform() : fmi2TypesPlatform;
}

FMI2_Export const char *fmi2GetVersion(void)
{
    return loaded ? real.fmi2GetVersion() : fmi2Version;
}

/* Log through the host's logger with the message already formatted. The logger is
 * variadic, but a host may pass a plain callback that reads only the message (a ctypes
 * CFUNCTYPE, such as gyro_fmu's own co-simulation master): it would show "%s ... %s".
 * So format here, double every '%' (a formatting host prints it once) and pass no
 * arguments. */
static void say(fmi2CallbackLogger logger, fmi2ComponentEnvironment env, fmi2String name,
                fmi2Status status, fmi2String category, const char *fmt, ...)
{
    char text[8192], safe[2 * 8192];
    size_t k = 0;
    const char *p;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    for (p = text; *p && k + 2 < sizeof safe; p++) {
        if (*p == '%') safe[k++] = '%';
        safe[k++] = *p;
    }
    safe[k] = '\0';
    if (logger)
        logger(env, name, status, category, safe);
    else
        fprintf(stderr, "%s\n", text);
}

/* ------------------------------------------------------------------------ */
/* Instances: the real component plus what the slave reported              */
/* ------------------------------------------------------------------------ */
struct instance {
    struct instance *next;           /* the live instances, a list (live_instance) */
    fmi2Component real;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    char name[256];
    int call_status;                 /* least status of the running call (slave's report) */
    int failed;                      /* the slave can no longer step */
    char why[2048];                  /* the slave's reason, for the fmi2Terminated answer */
    int mode;                        /* M_*: where the FMI 2.0 state machine stands */
    struct saved *states;            /* the FMU states this instance gave and not yet freed */
};

/* pythonfmu 0.7.0 has no FMI state machine: a step before initialization, a free of a
 * freed FMU state or a second fmi2FreeInstance crashed the host. The loader keeps one per
 * instance, in the native layer's words (fmu_src/fmi/instance.c): a call not allowed in
 * the current mode, a step size that is not finite and > 0, an FMU state this instance
 * did not give (or freed already) are refused with fmi2Error and a logged reason, and
 * change nothing. Value references and causalities are the slave's to check. */
enum { M_INST = 1, M_INIT = 2, M_STEP = 4, M_TERM = 8, M_ERROR = 16, M_ANY = 31 };

struct saved {
    struct saved *next;
    fmi2FMUstate state;
    int mode;                        /* the mode a fmi2SetFMUstate of it returns to */
};

static const char *mode_name(int mode)
{
    switch (mode) {
    case M_INST: return "instantiated mode";
    case M_INIT: return "initialization mode";
    case M_STEP: return "step mode";
    case M_TERM: return "terminated mode";
    default: return "error mode";
    }
}
static __thread struct instance *current;   /* the instance whose call is running here */
static struct instance *live;                /* every instance not yet freed (lock()) */

/* Whether c is a live instance of this loader: a host may free an instance twice, or call
 * a freed one (pythonfmu 0.7.0 aborts the process on a second fmi2FreeInstance). */
static int live_instance(const void *c)
{
    const struct instance *i;
    int found = 0;
    lock();
    for (i = live; i && !found; i = i->next) found = i == c;
    unlock();
    return found;
}

/* Called by the slave (ctypes) during an FMI call on `current`. */
FMI2_Export void pythonfmu_shim_report(int call_status, int failed, const char *why)
{
    struct instance *i = current;
    if (!i) return;
    if (call_status > i->call_status) i->call_status = call_status;
    i->failed = failed;
    copy(i->why, why ? why : "", sizeof i->why);
}

/* Whether call may run on i now; if not, says why through the host's logger. */
static int allowed(struct instance *i, const char *call, int modes)
{
    if (i->mode & modes) return 1;
    if (i->mode == M_ERROR)
        say(i->logger, i->env, i->name, fmi2Error, "logStatusError", "%s refused: the "
            "instance failed (%s); reset it, restore an FMU state saved before, or "
            "instantiate anew", call, i->why[0] ? i->why : "?");
    else
        say(i->logger, i->env, i->name, fmi2Error, "logStatusError",
            "%s is not allowed in %s (FMI 2.0 state machine)", call, mode_name(i->mode));
    return 0;
}

/* The saved record of state s of i, NULL when i did not give it (or it was freed). */
static struct saved **saved_of(struct instance *i, fmi2FMUstate s)
{
    struct saved **p;
    for (p = &i->states; *p; p = &(*p)->next)
        if ((*p)->state == s) return p;
    return NULL;
}

static fmi2Status not_a_state(struct instance *i, const char *call)
{
    say(i->logger, i->env, i->name, fmi2Error, "logStatusError", "%s: the FMU state given "
        "is not a live FMU state of this instance (freed already, or never given by "
        "fmi2GetFMUstate)", call);
    return fmi2Error;
}

/* After a call on i: a slave that can no longer step puts an initialized i in error mode
 * (a refused parameter before that fails the initialization, which goes on to say so). */
static fmi2Status after(struct instance *i, fmi2Status status, int next_mode)
{
    if (status <= fmi2Warning && next_mode) i->mode = next_mode;
    if (i->failed && (i->mode & (M_STEP | M_TERM))) i->mode = M_ERROR;
    return status;
}

/* pythonfmu 0.7.0 turns the resource URI into a path by cutting "file://" and decodes
 * nothing, so a folder with a character a URI escapes (non-ASCII, space, # % $ + ...)
 * named a folder that does not exist (and the host segfaulted). Hand it file:// and the
 * percent-decoded path instead. */
static int hexval(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

static const char *decoded_uri(const char *uri, char *out, size_t size)
{
    const char *p = uri;
    size_t j;
    if (!uri || strncmp(uri, "file:", 5) != 0) return uri;
    p += 5;
    if (strncmp(p, "//localhost/", 12) == 0) p += 11;
    else if (strncmp(p, "//", 2) == 0) p += 2;
    copy(out, "file://", size);
    j = strlen(out);
    while (*p && j + 1 < size) {
        if (p[0] == '%' && hexval(p[1]) >= 0 && hexval(p[2]) >= 0) {
            out[j++] = (char)(hexval(p[1]) * 16 + hexval(p[2]));
            p += 3;
        } else {
            out[j++] = *p++;
        }
    }
    out[j] = '\0';
    return *p ? uri : out; /* too long for the buffer: pass it as it came */
}

FMI2_Export fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
                                          fmi2String fmuGUID, fmi2String fmuResourceLocation,
                                          const fmi2CallbackFunctions *functions,
                                          fmi2Boolean visible, fmi2Boolean loggingOn)
{
    char err[8192] = "", info[8192] = "", uri[8192];
    struct instance *i, *outer;
    fmi2CallbackLogger logger = functions ? functions->logger : NULL;
    fmi2ComponentEnvironment env = functions ? functions->componentEnvironment : NULL;
    if (!ensure_loaded(err, sizeof err, info, sizeof info)) {
        say(logger, env, instanceName, fmi2Error, "logStatusError", "%s: %s", SHIM_VERSION, err);
        return NULL;
    }
    if (loggingOn && logger && info[0])
        say(logger, env, instanceName, fmi2OK, "logAll", "%s: %s", SHIM_VERSION, info);
    if (warnings[0] && !__atomic_exchange_n(&warnings_reported, 1, __ATOMIC_ACQ_REL))
        say(logger, env, instanceName, fmi2Warning, "logStatusWarning", "%s: %s", SHIM_VERSION,
            warnings);
    i = (struct instance *)calloc(1, sizeof *i);
    if (!i) return NULL;
    i->logger = logger;
    i->env = env;
    copy(i->name, instanceName ? instanceName : "", sizeof i->name);
    outer = current;
    current = i;
    i->real = real.fmi2Instantiate(instanceName, fmuType, fmuGUID,
                                   decoded_uri(fmuResourceLocation, uri, sizeof uri),
                                   functions, visible, loggingOn);
    current = outer;
    if (!i->real) {
        free(i);
        return NULL;
    }
    i->mode = M_INST;
    lock();
    i->next = live;
    live = i;
    unlock();
    return (fmi2Component)i;
}

FMI2_Export void fmi2FreeInstance(fmi2Component c)
{
    struct instance *i = (struct instance *)c, *outer, **p;
    int found = 0;
    if (!loaded || !i) return;
    lock();
    for (p = &live; *p; p = &(*p)->next)
        if (*p == i) {
            *p = i->next;
            found = 1;
            break;
        }
    unlock();
    if (!found) return; /* freed already (or never ours): ignored, as the native layer does */
    outer = current;
    current = i;
    while (i->states) {
        struct saved *s = i->states;
        i->states = s->next;
        real.fmi2FreeFMUstate(i->real, &s->state);
        free(s);
    }
    real.fmi2FreeInstance(i->real);
    current = outer;
    free(i);
}

/* Functions on an instance: only reachable after a successful fmi2Instantiate, in the
 * modes given (else refused, `allowed`); next: the mode after success (0: unchanged). The
 * status returned is the real one or the higher one the slave reported during it. */
#define FORWARD(name, modes, next, params, args)                       \
    FMI2_Export fmi2Status name params                                 \
    {                                                                  \
        struct instance *i = (struct instance *)c, *outer;             \
        fmi2Status status_;                                            \
        if (!loaded || !i || !live_instance(i)) return fmi2Error;       \
        if (!allowed(i, #name, modes)) return fmi2Error;               \
        outer = current;                                               \
        current = i;                                                   \
        i->call_status = fmi2OK;                                       \
        status_ = real.name args;                                      \
        current = outer;                                               \
        return after(i, status_ >= i->call_status ? status_ : (fmi2Status)i->call_status, \
                     next);                                            \
    }
#define RC (i->real)
#define GETTABLE (M_INIT | M_STEP | M_TERM | M_ERROR)
#define SETTABLE (M_INST | M_INIT | M_STEP)

typedef const fmi2ValueReference cvr_t;
FORWARD(fmi2SetDebugLogging, M_ANY, 0,
        (fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]), (RC, on, n, cat))
FORWARD(fmi2SetupExperiment, M_INST, 0, (fmi2Component c, fmi2Boolean td, fmi2Real tol,
                                         fmi2Real t0, fmi2Boolean sd, fmi2Real t1),
        (RC, td, tol, t0, sd, t1))
FORWARD(fmi2EnterInitializationMode, M_INST, M_INIT, (fmi2Component c), (RC))
FORWARD(fmi2ExitInitializationMode, M_INIT, M_STEP, (fmi2Component c), (RC))
FORWARD(fmi2Terminate, M_STEP | M_ERROR, M_TERM, (fmi2Component c), (RC))
FORWARD(fmi2GetReal, GETTABLE, 0, (fmi2Component c, cvr_t vr[], size_t n, fmi2Real v[]),
        (RC, vr, n, v))
FORWARD(fmi2GetInteger, GETTABLE, 0, (fmi2Component c, cvr_t vr[], size_t n, fmi2Integer v[]),
        (RC, vr, n, v))
FORWARD(fmi2GetBoolean, GETTABLE, 0, (fmi2Component c, cvr_t vr[], size_t n, fmi2Boolean v[]),
        (RC, vr, n, v))
FORWARD(fmi2GetString, GETTABLE, 0, (fmi2Component c, cvr_t vr[], size_t n, fmi2String v[]),
        (RC, vr, n, v))
FORWARD(fmi2SetReal, SETTABLE, 0, (fmi2Component c, cvr_t vr[], size_t n, const fmi2Real v[]),
        (RC, vr, n, v))
FORWARD(fmi2SetInteger, SETTABLE, 0,
        (fmi2Component c, cvr_t vr[], size_t n, const fmi2Integer v[]), (RC, vr, n, v))
FORWARD(fmi2SetBoolean, SETTABLE, 0,
        (fmi2Component c, cvr_t vr[], size_t n, const fmi2Boolean v[]), (RC, vr, n, v))
FORWARD(fmi2SetString, SETTABLE, 0,
        (fmi2Component c, cvr_t vr[], size_t n, const fmi2String v[]), (RC, vr, n, v))
FORWARD(fmi2GetDirectionalDerivative, M_ANY, 0,
        (fmi2Component c, cvr_t u[], size_t nu, cvr_t k[], size_t nk, const fmi2Real dk[],
         fmi2Real du[]), (RC, u, nu, k, nk, dk, du))
FORWARD(fmi2SetRealInputDerivatives, M_ANY, 0,
        (fmi2Component c, cvr_t vr[], size_t n, const fmi2Integer order[], const fmi2Real v[]),
        (RC, vr, n, order, v))
FORWARD(fmi2GetRealOutputDerivatives, M_ANY, 0,
        (fmi2Component c, cvr_t vr[], size_t n, const fmi2Integer order[], fmi2Real v[]),
        (RC, vr, n, order, v))
FORWARD(fmi2CancelStep, M_STEP, 0, (fmi2Component c), (RC))
FORWARD(fmi2GetStatus, M_ANY, 0, (fmi2Component c, const fmi2StatusKind s, fmi2Status *v),
        (RC, s, v))
FORWARD(fmi2GetRealStatus, M_ANY, 0, (fmi2Component c, const fmi2StatusKind s, fmi2Real *v),
        (RC, s, v))
FORWARD(fmi2GetIntegerStatus, M_ANY, 0,
        (fmi2Component c, const fmi2StatusKind s, fmi2Integer *v), (RC, s, v))
FORWARD(fmi2GetStringStatus, M_ANY, 0,
        (fmi2Component c, const fmi2StatusKind s, fmi2String *v), (RC, s, v))

/* One call of the real binary on i, with the slave's reported status folded in. */
#define CALL(expr)                                                     \
    do {                                                               \
        struct instance *outer_ = current;                             \
        current = i;                                                   \
        i->call_status = fmi2OK;                                       \
        status = (expr);                                               \
        current = outer_;                                              \
        if (status < i->call_status) status = (fmi2Status)i->call_status; \
    } while (0)

#define INSTANCE_OR_ERROR()                                            \
    struct instance *i = (struct instance *)c;                         \
    fmi2Status status;                                                 \
    if (!loaded || !i || !live_instance(i)) return fmi2Error

FMI2_Export fmi2Status fmi2Reset(fmi2Component c)
{
    INSTANCE_OR_ERROR();
    CALL(real.fmi2Reset(RC));
    if (status <= fmi2Warning) {
        i->failed = 0;
        i->why[0] = '\0';
        i->mode = M_INST;
    }
    return status;
}

FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSet)
{
    INSTANCE_OR_ERROR();
    if (!allowed(i, "fmi2DoStep", M_STEP)) return fmi2Error;
    if (!(h > 0.0 && h < 1e300 && t == t && t - t == 0.0)) {
        say(i->logger, i->env, i->name, fmi2Error, "logStatusError", "fmi2DoStep refused: "
            "communication step size %g s must be > 0 and finite (at the communication "
            "point %g s)", h, t);
        return fmi2Error;
    }
    CALL(real.fmi2DoStep(RC, t, h, noSet));
    return after(i, status, 0);
}

FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    struct saved *rec;
    fmi2FMUstate given;
    INSTANCE_OR_ERROR();
    if (!s) return fmi2Error;
    given = *s;
    if (given && saved_of(i, given)) { /* update a state given before, in place */
        CALL(real.fmi2GetFMUstate(RC, s));
        if (status <= fmi2Warning) (*saved_of(i, given))->mode = i->mode;
        return status;
    }
    if (given) return not_a_state(i, "fmi2GetFMUstate");
    rec = (struct saved *)calloc(1, sizeof *rec);
    if (!rec) return fmi2Error;
    CALL(real.fmi2GetFMUstate(RC, s));
    if (status > fmi2Warning || !*s) {
        free(rec);
        return status > fmi2Warning ? status : fmi2Error;
    }
    rec->state = *s;
    rec->mode = i->mode;
    rec->next = i->states;
    i->states = rec;
    return status;
}

FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s)
{
    struct saved **rec;
    INSTANCE_OR_ERROR();
    rec = saved_of(i, s);
    if (!rec) return not_a_state(i, "fmi2SetFMUstate");
    CALL(real.fmi2SetFMUstate(RC, s));
    return after(i, status, (*rec)->mode); /* the slave reports whether it failed */
}

FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    struct saved **rec, *gone;
    INSTANCE_OR_ERROR();
    if (!s || !*s) return fmi2OK; /* the standard: freeing NULL does nothing */
    rec = saved_of(i, *s);
    if (!rec) return not_a_state(i, "fmi2FreeFMUstate");
    gone = *rec;
    *rec = gone->next;
    free(gone);
    CALL(real.fmi2FreeFMUstate(RC, s));
    *s = NULL;
    return status;
}

FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n)
{
    INSTANCE_OR_ERROR();
    if (!saved_of(i, s)) return not_a_state(i, "fmi2SerializedFMUstateSize");
    CALL(real.fmi2SerializedFMUstateSize(RC, s, n));
    return status;
}

FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[],
                                             size_t n)
{
    INSTANCE_OR_ERROR();
    if (!saved_of(i, s)) return not_a_state(i, "fmi2SerializeFMUstate");
    CALL(real.fmi2SerializeFMUstate(RC, s, b, n));
    return status;
}

FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n,
                                               fmi2FMUstate *s)
{
    struct saved *rec;
    INSTANCE_OR_ERROR();
    if (!s) return fmi2Error;
    if (*s && !saved_of(i, *s)) return not_a_state(i, "fmi2DeSerializeFMUstate");
    rec = *s ? NULL : (struct saved *)calloc(1, sizeof *rec);
    if (!*s && !rec) return fmi2Error;
    CALL(real.fmi2DeSerializeFMUstate(RC, b, n, s));
    if (status > fmi2Warning || !*s) {
        free(rec);
        return status > fmi2Warning ? status : fmi2Error;
    }
    if (rec) {
        rec->state = *s;
        rec->next = i->states;
        i->states = rec;
    } else {
        rec = *saved_of(i, *s);
    }
    rec->mode = M_STEP; /* a state from bytes restores a stepping instance */
    return status;
}

/* fmi2Terminated answered here: pythonfmu's binary says true after any fmi2Discard. */
FMI2_Export fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s,
                                            fmi2Boolean *v)
{
    struct instance *i = (struct instance *)c, *outer;
    fmi2Status status;
    if (!loaded || !i || !live_instance(i)) return fmi2Error;
    if (s != fmi2Terminated) {
        outer = current;
        current = i;
        status = real.fmi2GetBooleanStatus(i->real, s, v);
        current = outer;
        return status;
    }
    if (!v) return fmi2Error;
    if (!i->failed) {
        *v = fmi2False;  /* a recoverable refusal: the host may retry or go on */
        return fmi2OK;
    }
    *v = fmi2True;
    if (i->logger)
        say(i->logger, i->env, i->name, fmi2Error, "logStatusError",
            "%s cannot go on (fmi2GetBooleanStatus(fmi2Terminated) answers fmi2Error, not a "
            "normal end of the simulation): %s", i->name, i->why[0] ? i->why : "?");
    return fmi2Error;
}
