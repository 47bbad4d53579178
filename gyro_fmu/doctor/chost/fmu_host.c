/*
 * fmu_host.c - the smallest FMI 2.0 co-simulation importer that `gyro-fmu doctor`
 * compiles on the spot to check that a non-Python host can load our FMUs.
 *
 * It does what OMSimulator, Simulink or Dymola do with a co-simulation FMU,
 * and nothing else: dlopen the binary (RTLD_NOW | RTLD_LOCAL, as FMI Library
 * does), instantiate with a logger, set up the experiment, initialize, hold the
 * given inputs over NSTEPS doSteps, print the requested outputs after every
 * step, terminate, free the instance and dlclose. Every line is flushed at once
 * so that a crash at process exit cannot swallow what came before; the last
 * line before `return` is "host: returning from main", so a signal after it
 * means the crash happened in exit-time teardown, not in the simulation.
 *
 * usage: fmu_host LIBRARY GUID RESOURCE_URI STEP NSTEPS [-s VR=VALUE]... [-o VR]...
 *                 [-f INPUTS] [--no-free] [--no-dlclose]
 *
 * -f INPUTS: a text file of one row per communication point, each row the values of the
 * -s variables in their order (row 0 is set before initialization, row k-1 is held over
 * step k), as a reference run's input table has them.
 *
 * exit status: 0 ok, 1 usage, 2 dlopen failed, 3 symbol missing,
 *              4 fmi2Instantiate returned NULL, 5 an FMI call returned
 *              fmi2Error or fmi2Fatal (or fmi2Discard from doStep).
 *
 * Build: cc -O1 -o fmu_host fmu_host.c -ldl
 *        (add -DHAVE_FMI2_HEADERS -I<dir of fmi2FunctionTypes.h> to use the
 *        standard headers, e.g. the ones fmpy ships in fmpy/c-code).
 */

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#define LIB_HANDLE HMODULE
#define LIB_OPEN(p) LoadLibraryA(p)
#define LIB_SYM(h, n) ((void *)GetProcAddress((h), (n)))
#define LIB_CLOSE(h) FreeLibrary(h)
static const char *lib_error(void) { return "LoadLibrary failed (see GetLastError)"; }
#else
#include <dlfcn.h>
#define LIB_HANDLE void *
#define LIB_OPEN(p) dlopen((p), RTLD_NOW | RTLD_LOCAL)
#define LIB_SYM(h, n) dlsym((h), (n))
#define LIB_CLOSE(h) dlclose(h)
static const char *lib_error(void) { const char *e = dlerror(); return e ? e : "?"; }
#endif

#ifdef HAVE_FMI2_HEADERS
#include "fmi2FunctionTypes.h"
#else
/* The few FMI 2.0 types this host needs (identical to fmi2FunctionTypes.h). */
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Boolean;
typedef const char *fmi2String;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String,
                                   fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);
typedef struct {
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2StepFinished stepFinished;
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;
typedef fmi2Component fmi2InstantiateTYPE(fmi2String, fmi2Type, fmi2String, fmi2String,
                                          const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
typedef void fmi2FreeInstanceTYPE(fmi2Component);
typedef fmi2Status fmi2SetupExperimentTYPE(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real,
                                           fmi2Boolean, fmi2Real);
typedef fmi2Status fmi2EnterInitializationModeTYPE(fmi2Component);
typedef fmi2Status fmi2ExitInitializationModeTYPE(fmi2Component);
typedef fmi2Status fmi2TerminateTYPE(fmi2Component);
typedef fmi2Status fmi2GetRealTYPE(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]);
typedef fmi2Status fmi2SetRealTYPE(fmi2Component, const fmi2ValueReference[], size_t,
                                   const fmi2Real[]);
typedef fmi2Status fmi2DoStepTYPE(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
#endif

#define MAX_VARS 64

static const char *status_name(fmi2Status s)
{
    static const char *names[] = {"OK", "Warning", "Discard", "Error", "Fatal", "Pending"};
    return (s >= 0 && s <= 5) ? names[s] : "?";
}

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    char text[4096];
    va_list args;
    (void)env;
    va_start(args, message);
    vsnprintf(text, sizeof text, message ? message : "", args);
    va_end(args);
    printf("log: [%s] %s %s: %s\n", instance ? instance : "", status_name(status),
           category ? category : "", text);
    fflush(stdout);
}

static void *sym(LIB_HANDLE lib, const char *name)
{
    void *f = LIB_SYM(lib, name);
    if (!f) {
        printf("host: symbol %s missing: %s\n", name, lib_error());
        fflush(stdout);
        exit(3);
    }
    return f;
}

/* An FMI call that must not fail: report and leave with status 5 otherwise. */
static int ok(const char *what, fmi2Status s)
{
    printf("host: %s -> %s\n", what, status_name(s));
    fflush(stdout);
    return s == fmi2OK || s == fmi2Warning;
}

int main(int argc, char **argv)
{
    fmi2ValueReference in_vr[MAX_VARS], out_vr[MAX_VARS];
    fmi2Real in_val[MAX_VARS], out_val[MAX_VARS];
    size_t n_in = 0, n_out = 0;
    int do_free = 1, do_close = 1, i;
    double *rows = NULL;
    long n_rows = 0;
    const char *input_file = NULL;
    double h, t = 0.0;
    long n_steps, k;

    setvbuf(stdout, NULL, _IONBF, 0);
    if (argc < 6) {
        fprintf(stderr,
                "usage: %s LIBRARY GUID RESOURCE_URI STEP NSTEPS [-s VR=VALUE]... [-o VR]... "
                "[--no-free] [--no-dlclose]\n", argv[0]);
        return 1;
    }
    h = strtod(argv[4], NULL);
    n_steps = strtol(argv[5], NULL, 10);
    for (i = 6; i < argc; i++) {
        if (!strcmp(argv[i], "-s") && i + 1 < argc && n_in < MAX_VARS) {
            char *eq = strchr(argv[++i], '=');
            if (!eq) return 1;
            in_vr[n_in] = (fmi2ValueReference)strtoul(argv[i], NULL, 10);
            in_val[n_in++] = strtod(eq + 1, NULL);
        } else if (!strcmp(argv[i], "-o") && i + 1 < argc && n_out < MAX_VARS) {
            out_vr[n_out++] = (fmi2ValueReference)strtoul(argv[++i], NULL, 10);
        } else if (!strcmp(argv[i], "-f") && i + 1 < argc) {
            input_file = argv[++i];
        } else if (!strcmp(argv[i], "--no-free")) {
            do_free = 0;
        } else if (!strcmp(argv[i], "--no-dlclose")) {
            do_close = 0;
        } else {
            fprintf(stderr, "fmu_host: bad argument %s\n", argv[i]);
            return 1;
        }
    }

    if (input_file) {
        FILE *fin = fopen(input_file, "r");
        double v;
        long n_values = 0, cap = 1024;
        if (!fin || !n_in || !(rows = malloc(cap * sizeof *rows))) return 1;
        while (fscanf(fin, "%lf", &v) == 1) {
            if (n_values == cap && !(rows = realloc(rows, (cap *= 2) * sizeof *rows))) return 1;
            rows[n_values++] = v;
        }
        fclose(fin);
        n_rows = n_values / (long)n_in;
        if (n_rows < n_steps + 1) {
            fprintf(stderr, "fmu_host: %ld input rows for %ld steps\n", n_rows, n_steps);
            return 1;
        }
        for (size_t j = 0; j < n_in; j++) in_val[j] = rows[j];
    }

    LIB_HANDLE lib = LIB_OPEN(argv[1]);
    if (!lib) {
        printf("host: dlopen %s failed: %s\n", argv[1], lib_error());
        return 2;
    }
    printf("host: loaded %s\n", argv[1]);

    fmi2InstantiateTYPE *instantiate = (fmi2InstantiateTYPE *)sym(lib, "fmi2Instantiate");
    fmi2FreeInstanceTYPE *free_instance = (fmi2FreeInstanceTYPE *)sym(lib, "fmi2FreeInstance");
    fmi2SetupExperimentTYPE *setup = (fmi2SetupExperimentTYPE *)sym(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter_init =
        (fmi2EnterInitializationModeTYPE *)sym(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *exit_init =
        (fmi2ExitInitializationModeTYPE *)sym(lib, "fmi2ExitInitializationMode");
    fmi2TerminateTYPE *terminate = (fmi2TerminateTYPE *)sym(lib, "fmi2Terminate");
    fmi2GetRealTYPE *get_real = (fmi2GetRealTYPE *)sym(lib, "fmi2GetReal");
    fmi2SetRealTYPE *set_real = (fmi2SetRealTYPE *)sym(lib, "fmi2SetReal");
    fmi2DoStepTYPE *do_step = (fmi2DoStepTYPE *)sym(lib, "fmi2DoStep");

    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("doctor", fmi2CoSimulation, argv[2], argv[3], &callbacks, 0, 1);
    if (!c) {
        printf("host: fmi2Instantiate returned NULL\n");
        return 4;
    }
    printf("host: instantiated\n");

    if (!ok("fmi2SetupExperiment", setup(c, 0, 0.0, 0.0, 0, 0.0))) return 5;
    if (!ok("fmi2EnterInitializationMode", enter_init(c))) return 5;
    if (n_in && !ok("fmi2SetReal (inputs)", set_real(c, in_vr, n_in, in_val))) return 5;
    if (!ok("fmi2ExitInitializationMode", exit_init(c))) return 5;

    for (k = 1; k <= n_steps; k++) {
        fmi2Status s;
        if (rows)
            for (size_t j = 0; j < n_in; j++) in_val[j] = rows[(k - 1) * (long)n_in + (long)j];
        if (n_in && (s = set_real(c, in_vr, n_in, in_val)) > fmi2Warning) {
            ok("fmi2SetReal", s);
            return 5;
        }
        if ((s = do_step(c, t, h, 1)) > fmi2Warning) {
            ok("fmi2DoStep", s);
            return 5;
        }
        t = (double)k * h; /* no accumulated rounding in the time grid */
        if (n_out && (s = get_real(c, out_vr, n_out, out_val)) > fmi2Warning) {
            ok("fmi2GetReal", s);
            return 5;
        }
        printf("step %ld t=%.17g", k, t);
        for (size_t j = 0; j < n_out; j++) printf(" %u=%.17g", out_vr[j], out_val[j]);
        printf("\n");
    }

    if (!ok("fmi2Terminate", terminate(c))) return 5;
    if (do_free) {
        free_instance(c);
        printf("host: freed instance\n");
    }
    if (do_close) {
        LIB_CLOSE(lib);
        printf("host: closed library\n");
    }
    free(rows);
    printf("host: returning from main\n");
    return 0;
}
