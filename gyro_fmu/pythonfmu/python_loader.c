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
 *           -o shim.so loader.c \
 *           -Wl,--no-as-needed -l:libdl.so.2
 * Only GLIBC_2.2.5 symbols are referenced (see the .symver lines below), so the
 * loader itself loads on any x86_64 glibc and can report a too-old glibc for
 * the real binary (which needs GLIBC_2.32 and GLIBCXX_3.4.30) instead of the
 * host failing at dlopen.
 */

#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <sched.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fmi2Functions.h"

#if defined(__x86_64__) && defined(__GLIBC__)
/* Bind to the oldest versions (glibc >= 2.34 moved dl* into libc as GLIBC_2.34). */
__asm__(".symver dlopen,dlopen@GLIBC_2.2.5");
__asm__(".symver dlsym,dlsym@GLIBC_2.2.5");
__asm__(".symver dladdr,dladdr@GLIBC_2.2.5");
__asm__(".symver dlerror,dlerror@GLIBC_2.2.5");
#endif

#define SHIM_VERSION "pythonfmu-shim 1"
#define MAXPATH 4096
#define MAXENTRIES 32

/* Marker that gyro_fmu/pythonfmu/loader.py looks for to recognise an installed loader. */
__attribute__((used)) static const char shim_marker[] = "@(#)" SHIM_VERSION;

/* ------------------------------------------------------------------------ */
/* The real binary's functions                                              */
/* ------------------------------------------------------------------------ */
#define FMI2_CS_FUNCTIONS(X) \
    X(fmi2SetDebugLogging) X(fmi2Instantiate) X(fmi2FreeInstance) X(fmi2SetupExperiment) \
    X(fmi2EnterInitializationMode) X(fmi2ExitInitializationMode) X(fmi2Terminate) \
    X(fmi2Reset) X(fmi2GetReal) X(fmi2GetInteger) X(fmi2GetBoolean) X(fmi2GetString) \
    X(fmi2SetReal) X(fmi2SetInteger) X(fmi2SetBoolean) X(fmi2SetString) \
    X(fmi2GetFMUstate) X(fmi2SetFMUstate) X(fmi2FreeFMUstate) X(fmi2SerializedFMUstateSize) \
    X(fmi2SerializeFMUstate) X(fmi2DeSerializeFMUstate) X(fmi2GetDirectionalDerivative) \
    X(fmi2SetRealInputDerivatives) X(fmi2GetRealOutputDerivatives) X(fmi2DoStep) \
    X(fmi2CancelStep) X(fmi2GetStatus) X(fmi2GetRealStatus) X(fmi2GetIntegerStatus) \
    X(fmi2GetBooleanStatus) X(fmi2GetStringStatus) X(fmi2GetTypesPlatform) X(fmi2GetVersion)

static struct {
#define X(name) name##TYPE *name;
    FMI2_CS_FUNCTIONS(X)
#undef X
} real;

/* ------------------------------------------------------------------------ */
/* State (guarded by a spin lock: no pthread symbols, see the header)       */
/* ------------------------------------------------------------------------ */
static volatile int lock_word;
static volatile int loaded;          /* real.* filled in */
static void *real_handle;
static char self_path[MAXPATH], fmu_root[MAXPATH], env_file[MAXPATH + 64], real_path[MAXPATH + 64];

struct env_file_values {
    char libpython[MAXPATH];
    char home[MAXPATH];
    char version[32];                /* "3.11" */
    char executable[MAXPATH];        /* informative: the interpreter that built the FMU */
    char paths[MAXENTRIES][MAXPATH];
    int npaths;
};
static struct env_file_values cfg;
static char warnings[4096];          /* reported once, through the first logger */
static int warnings_reported;

static void lock(void)
{
    while (__atomic_exchange_n(&lock_word, 1, __ATOMIC_ACQUIRE)) sched_yield();
}
static void unlock(void) { __atomic_store_n(&lock_word, 0, __ATOMIC_RELEASE); }

static int verbose(void)
{
    const char *v = getenv("PYTHONFMU_SHIM_VERBOSE");
    return v && *v && strcmp(v, "0") != 0;
}

static void trace(const char *fmt, ...)
{
    va_list ap;
    if (!verbose()) return;
    fputs("[pythonfmu-shim] ", stderr);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
}

/* Append to a bounded message buffer. */
static void add(char *buf, size_t size, const char *fmt, ...)
{
    size_t len = strlen(buf);
    va_list ap;
    if (len + 1 >= size) return;
    va_start(ap, fmt);
    vsnprintf(buf + len, size - len, fmt, ap);
    va_end(ap);
}

static int is_file(const char *path) { return path[0] && access(path, R_OK) == 0; }

static void copy(char *dst, const char *src, size_t size)
{
    size_t n = strlen(src);
    if (n >= size) n = size - 1;
    memmove(dst, src, n);
    dst[n] = '\0';
}

/* ------------------------------------------------------------------------ */
/* Step 1: where am I, what does python_env.txt say                         */
/* ------------------------------------------------------------------------ */
static int locate(char *err, size_t size)
{
    Dl_info info;
    char *slash;
    int i;
    if (self_path[0]) return 1;
    if (!dladdr((void *)&locate, &info) || !info.dli_fname || !info.dli_fname[0]) {
        add(err, size, "cannot find the path of the FMU binary (dladdr failed)");
        return 0;
    }
    if (!realpath(info.dli_fname, self_path)) copy(self_path, info.dli_fname, sizeof self_path);
    /* <root>/binaries/linux64/<id>.so -> <root>, and <id>_pythonfmu.so next to it */
    copy(real_path, self_path, sizeof real_path);
    slash = strrchr(real_path, '.');
    if (slash && strcmp(slash, ".so") == 0) *slash = '\0';
    add(real_path, sizeof real_path, "_pythonfmu.so");
    copy(fmu_root, self_path, sizeof fmu_root);
    for (i = 0; i < 3; i++) {
        slash = strrchr(fmu_root, '/');
        if (!slash) break;
        *slash = '\0';
    }
    snprintf(env_file, sizeof env_file, "%s/resources/python_env.txt", fmu_root);
    return 1;
}

static void read_env_file(void)
{
    char line[MAXPATH + 64];
    FILE *f;
    memset(&cfg, 0, sizeof cfg);
    f = fopen(env_file, "r");
    if (!f) return;
    while (fgets(line, sizeof line, f)) {
        char *eq, *value, *end = line + strlen(line);
        while (end > line && (end[-1] == '\n' || end[-1] == '\r')) *--end = '\0';
        if (line[0] == '#' || !(eq = strchr(line, '='))) continue;
        *eq = '\0';
        value = eq + 1;
        if (!strcmp(line, "libpython")) copy(cfg.libpython, value, sizeof cfg.libpython);
        else if (!strcmp(line, "pythonhome")) copy(cfg.home, value, sizeof cfg.home);
        else if (!strcmp(line, "python_version")) copy(cfg.version, value, sizeof cfg.version);
        else if (!strcmp(line, "python_executable")) copy(cfg.executable, value, sizeof cfg.executable);
        else if (!strcmp(line, "pythonpath") && cfg.npaths < MAXENTRIES)
            copy(cfg.paths[cfg.npaths++], value, MAXPATH);
    }
    fclose(f);
}

/* ------------------------------------------------------------------------ */
/* Step 2: libpython and the interpreter's environment                      */
/* ------------------------------------------------------------------------ */
static void fix_hint(char *err, size_t size)
{
    add(err, size,
        " How to fix: rebuild the FMU with the Python you want it to use (`gyro-fmu build`, "
        "then `gyro_fmu/pythonfmu/loader.py`), or edit %s, or set in the importer's environment "
        "PYTHONFMU_LIBPYTHON=<path of libpython%s.so.1.0>, PYTHONHOME=<that Python's prefix> and "
        "PYTHONPATH=<its site-packages holding numpy and scipy> (LD_PRELOAD=<libpython> "
        "instead of PYTHONFMU_LIBPYTHON also works).",
        env_file, cfg.version[0] ? cfg.version : "3.X");
}

/* "prefix" or "prefix:exec_prefix": check <prefix>/lib/pythonX.Y/os.py */
static int home_ok(const char *home, char *landmark, size_t size)
{
    char prefix[MAXPATH - 64];
    char *colon;
    copy(prefix, home, sizeof prefix);
    if ((colon = strchr(prefix, ':'))) *colon = '\0';
    snprintf(landmark, size, "%s/lib/python%s/os.py", prefix, cfg.version[0] ? cfg.version : "3");
    if (!cfg.version[0]) return access(prefix, R_OK) == 0;
    return is_file(landmark);
}

static int path_has(const char *list, const char *entry)
{
    size_t n = strlen(entry);
    const char *p = list;
    while (p && *p) {
        const char *colon = strchr(p, ':');
        size_t len = colon ? (size_t)(colon - p) : strlen(p);
        if (len == n && strncmp(p, entry, n) == 0) return 1;
        p = colon ? colon + 1 : NULL;
    }
    return 0;
}

static int setup_python(char *err, size_t size, char *info, size_t isize)
{
    typedef int is_init_t(void);
    typedef const char *version_t(void);
    is_init_t *is_init = (is_init_t *)dlsym(RTLD_DEFAULT, "Py_IsInitialized");
    version_t *get_version;
    const char *lib = getenv("PYTHONFMU_LIBPYTHON");
    const char *home = getenv("PYTHONHOME");
    const char *old;
    char landmark[MAXPATH + 64], *newpath;
    size_t need;
    int i;

    if (is_init) {
        if (is_init()) {
            add(info, isize, "Python already running in the process; ");
            return 1;  /* the host is Python (fmpy...) or another FMU started it */
        }
        add(info, isize, "libpython already in the process (not initialized); ");
    } else {
        const char *source = "PYTHONFMU_LIBPYTHON";
        void *h;
        if (!lib || !*lib) {
            lib = cfg.libpython;
            source = env_file;
        }
        if (!lib[0]) {
            add(err, size, "cannot start Python: no libpython is configured (%s %s).", env_file,
                is_file(env_file) ? "has no libpython= line" : "is missing");
            fix_hint(err, size);
            return 0;
        }
        if (!is_file(lib)) {
            add(err, size, "cannot start Python: libpython %s (from %s) does not exist "
                "(Python %s of %s moved or removed?).", lib, source,
                cfg.version[0] ? cfg.version : "?", cfg.executable[0] ? cfg.executable : "?");
            fix_hint(err, size);
            return 0;
        }
        h = dlopen(lib, RTLD_NOW | RTLD_GLOBAL);
        if (!h) {
            const char *e = dlerror();
            add(err, size, "cannot start Python: dlopen(%s) failed: %s.", lib, e ? e : "?");
            fix_hint(err, size);
            return 0;
        }
        is_init = (is_init_t *)dlsym(h, "Py_IsInitialized");
        if (!is_init) {
            add(err, size, "cannot start Python: %s has no Py_IsInitialized, not a libpython.", lib);
            fix_hint(err, size);
            return 0;
        }
        add(info, isize, "loaded %s; ", lib);
        if (is_init()) return 1;
    }

    /* The interpreter is not initialized yet: pythonfmu's Py_Initialize will read the env. */
    get_version = (version_t *)dlsym(RTLD_DEFAULT, "Py_GetVersion");
    if (get_version && cfg.version[0]) {
        const char *v = get_version();
        size_t n = strlen(cfg.version);
        if (strncmp(v, cfg.version, n) != 0 || (v[n] >= '0' && v[n] <= '9')) {
            add(err, size, "cannot start Python: the libpython in the process is Python %.10s, "
                "but this FMU was built with Python %s (%s): its numpy/scipy will not import.",
                v, cfg.version, cfg.executable);
            fix_hint(err, size);
            return 0;
        }
    }
    if (home && *home) {
        if (!home_ok(home, landmark, sizeof landmark)) {
            add(err, size, "cannot start Python: PYTHONHOME=%s is set in the environment but "
                "%s does not exist (Py_Initialize would abort the process).", home, landmark);
            fix_hint(err, size);
            return 0;
        }
        add(info, isize, "kept PYTHONHOME=%s; ", home);
    } else {
        if (!cfg.home[0] || !home_ok(cfg.home, landmark, sizeof landmark)) {
            add(err, size, "cannot start Python: its standard library was not found: %s "
                "(pythonhome=%s in %s) does not exist (Py_Initialize would abort the process).",
                cfg.home[0] ? landmark : "(none)", cfg.home[0] ? cfg.home : "(none)", env_file);
            fix_hint(err, size);
            return 0;
        }
        setenv("PYTHONHOME", cfg.home, 1);
        add(info, isize, "PYTHONHOME=%s; ", cfg.home);
    }
    old = getenv("PYTHONPATH");
    need = (old ? strlen(old) : 0) + 2;
    for (i = 0; i < cfg.npaths; i++) need += strlen(cfg.paths[i]) + 1;
    newpath = (char *)malloc(need);
    if (newpath) {
        int added = 0;
        newpath[0] = '\0';
        for (i = 0; i < cfg.npaths; i++) {
            if (access(cfg.paths[i], X_OK) != 0) {
                add(warnings, sizeof warnings, "PYTHONPATH entry %s (from %s) does not exist, "
                    "numpy/scipy may not import; ", cfg.paths[i], env_file);
                continue;
            }
            if (old && path_has(old, cfg.paths[i])) continue;
            if (path_has(newpath, cfg.paths[i])) continue;
            if (newpath[0]) strcat(newpath, ":");
            strcat(newpath, cfg.paths[i]);
            added++;
        }
        if (old && *old) {
            if (newpath[0]) strcat(newpath, ":");
            strcat(newpath, old);
        }
        if (added) {
            setenv("PYTHONPATH", newpath, 1);
            add(info, isize, "PYTHONPATH=%s; ", newpath);
        }
        free(newpath);
    }
    return 1;
}

/* ------------------------------------------------------------------------ */
/* Step 3: the real binary                                                  */
/* ------------------------------------------------------------------------ */
static int load_real(char *err, size_t size)
{
    void *h;
    if (!is_file(real_path)) {
        add(err, size, "pythonfmu's binary %s is missing from the FMU (reinstall the shim with "
            "gyro_fmu/pythonfmu/loader.py).", real_path);
        return 0;
    }
    h = dlopen(real_path, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        const char *e = dlerror();
        add(err, size, "dlopen(%s) failed: %s (pythonfmu 0.7.0's binary needs glibc >= 2.32 and "
            "libstdc++ with GLIBCXX_3.4.30).", real_path, e ? e : "?");
        return 0;
    }
#define X(name)                                                               \
    real.name = (name##TYPE *)dlsym(h, #name);                                \
    if (!real.name) {                                                         \
        add(err, size, "%s has no symbol %s.", real_path, #name);             \
        return 0;                                                             \
    }
    FMI2_CS_FUNCTIONS(X)
#undef X
    real_handle = h;
    return 1;
}

/* Everything up to a loaded real binary; err gets the reason on failure. */
static int ensure_loaded(char *err, size_t size, char *info, size_t isize)
{
    int ok = 0;
    if (__atomic_load_n(&loaded, __ATOMIC_ACQUIRE)) return 1;
    lock();
    if (loaded) {
        ok = 1;
    } else if (locate(err, size)) {
        read_env_file();
        if (setup_python(err, size, info, isize) && load_real(err, size)) {
            add(info, isize, "forwarding to %s", real_path);
            __atomic_store_n(&loaded, 1, __ATOMIC_RELEASE);
            ok = 1;
        }
    }
    unlock();
    trace("%s: %s%s", self_path[0] ? self_path : "?", ok ? info : "FAILED: ", ok ? "" : err);
    return ok;
}

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
