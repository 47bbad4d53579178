/* The pythonfmu loader's environment (python_loader.c's header, steps 1-3): its own file
 * and the FMU root, resources/python_env.txt, libpython and the interpreter's
 * environment, pythonfmu's real binary and its functions; the shared state and helpers
 * (python_loader.h). */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <sched.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "python_loader.h"

struct real_functions real;

/* ------------------------------------------------------------------------ */
/* State (guarded by a spin lock: no pthread symbols, see the header)       */
/* ------------------------------------------------------------------------ */
static volatile int lock_word;
volatile int loaded;
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
char warnings[4096];
int warnings_reported;

void lock(void)
{
    while (__atomic_exchange_n(&lock_word, 1, __ATOMIC_ACQUIRE)) sched_yield();
}
void unlock(void) { __atomic_store_n(&lock_word, 0, __ATOMIC_RELEASE); }

static int verbose(void)
{
    const char *v = getenv("PYTHONFMU_SHIM_VERBOSE");
    return v && *v && strcmp(v, "0") != 0;
}

void trace(const char *fmt, ...)
{
    va_list ap;
    if (!verbose()) return;
    fputs("[pythonfmu-shim] ", stderr);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
}

void add(char *buf, size_t size, const char *fmt, ...)
{
    size_t len = strlen(buf);
    va_list ap;
    if (len + 1 >= size) return;
    va_start(ap, fmt);
    vsnprintf(buf + len, size - len, fmt, ap);
    va_end(ap);
}

static int is_file(const char *path) { return path[0] && access(path, R_OK) == 0; }

void copy(char *dst, const char *src, size_t size)
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

int ensure_loaded(char *err, size_t size, char *info, size_t isize)
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

