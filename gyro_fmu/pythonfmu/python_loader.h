/* What the pythonfmu loader's two files share (python_loader.c: the FMI 2.0 functions and
 * the instances; python_loader_env.c: finding Python and pythonfmu's binary, steps 1-3 of
 * python_loader.c's header). Hidden symbols: -fvisibility=hidden, nothing exported. */
#ifndef PYTHON_LOADER_H
#define PYTHON_LOADER_H

#include <stddef.h>

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

struct real_functions {
#define X(name) name##TYPE *name;
    FMI2_CS_FUNCTIONS(X)
#undef X
};
/* pythonfmu's binary's functions, filled in once loaded is 1. */
extern struct real_functions real;


extern volatile int loaded;          /* real.* filled in */
extern char warnings[4096];          /* reported once, through the first logger */
extern int warnings_reported;

/* A spin lock (no pthread symbols, see python_loader.c's header). */
void lock(void);
void unlock(void);
/* A line on stderr when PYTHONFMU_SHIM_VERBOSE is set and not 0. */
void trace(const char *fmt, ...);
/* Append to a bounded message buffer. */
void add(char *buf, size_t size, const char *fmt, ...);
/* Copy src into dst of size bytes, cut and terminated. */
void copy(char *dst, const char *src, size_t size);
/* Everything up to a loaded real binary (steps 1-3); err gets the reason on failure,
 * info what was done. 1 when loaded. */
int ensure_loaded(char *err, size_t size, char *info, size_t isize);

#endif
