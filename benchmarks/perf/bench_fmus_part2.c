/* Time fmi2DoStep of a built FMU's shared library directly (no Python in the loop).
 * usage: bench_fmus_part2 LIB GUID RESOURCE_URI STEP_S N [VR=VALUE ...]
 *   VR=VALUE sets a Real start value before initialisation (value reference VR),
 *   sVR=TEXT a String one.
 * Prints: ns_per_step <value>
 * pkmbench issue 4 (benchmarks/perf/bench_fmus_part2.py builds and drives it). */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    (void)env; (void)category;
    if (status >= fmi2Warning) fprintf(stderr, "%s: %s\n", name, message);
}

int main(int argc, char **argv)
{
    if (argc < 6) { fprintf(stderr, "usage: %s LIB GUID URI STEP N [VR=VALUE...]\n", argv[0]); return 2; }
    void *lib = dlopen(argv[1], RTLD_NOW);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 1; }
    fmi2InstantiateTYPE *inst = (fmi2InstantiateTYPE *)dlsym(lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = (fmi2SetupExperimentTYPE *)dlsym(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter = (fmi2EnterInitializationModeTYPE *)dlsym(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *leave = (fmi2ExitInitializationModeTYPE *)dlsym(lib, "fmi2ExitInitializationMode");
    fmi2SetRealTYPE *setReal = (fmi2SetRealTYPE *)dlsym(lib, "fmi2SetReal");
    fmi2SetStringTYPE *setString = (fmi2SetStringTYPE *)dlsym(lib, "fmi2SetString");
    fmi2DoStepTYPE *doStep = (fmi2DoStepTYPE *)dlsym(lib, "fmi2DoStep");
    fmi2TerminateTYPE *term = (fmi2TerminateTYPE *)dlsym(lib, "fmi2Terminate");
    fmi2FreeInstanceTYPE *freeInst = (fmi2FreeInstanceTYPE *)dlsym(lib, "fmi2FreeInstance");
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = inst("bench", fmi2CoSimulation, argv[2], argv[3], &cb, fmi2False, fmi2False);
    if (!c) { fprintf(stderr, "instantiate failed\n"); return 1; }
    double h = atof(argv[4]);
    long n = atol(argv[5]);
    setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
    for (int a = 6; a < argc; a++) {
        int is_string = argv[a][0] == 's';
        fmi2ValueReference vr = (fmi2ValueReference)atoi(argv[a] + is_string);
        const char *eq = strchr(argv[a], '=');
        if (!eq) continue;
        if (is_string) {
            fmi2String v = eq + 1;
            setString(c, &vr, 1, &v);
        } else {
            fmi2Real v = atof(eq + 1);
            setReal(c, &vr, 1, &v);
        }
    }
    if (enter(c) > fmi2Warning || leave(c) > fmi2Warning) { fprintf(stderr, "initialisation failed\n"); return 1; }
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    double t = 0.0;
    for (long k = 0; k < n; k++) {
        if (doStep(c, t, h, fmi2True) > fmi2Warning) { fprintf(stderr, "doStep failed at %ld\n", k); return 1; }
        t += h;
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double ns = ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / (double)n;
    printf("ns_per_step %.3f\n", ns);
    term(c);
    freeInst(c);
    return 0;
}
