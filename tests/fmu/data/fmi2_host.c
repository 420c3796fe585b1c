/* A minimal FMI 2.0 co-simulation host for Windows, for tests/fmu/test_windows.py: load the DLL, run N steps
   of 1/256 s, print the 8 outputs (value references 1000-1007) of every sample. */
#include <stdio.h>
#include <stdlib.h>
#include <windows.h>
typedef void *C;
typedef void (*Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct { Logger logger; void *a, *f, *s; void *env; } Callbacks;
static void lg(void *e, const char *n, int s, const char *c, const char *m, ...) { (void)e; (void)n; (void)s; (void)c; fprintf(stderr, "%s\n", m); }
int main(int argc, char **argv) {
    HMODULE h = LoadLibraryA(argv[1]);
    if (!h) { fprintf(stderr, "cannot load %s\n", argv[1]); return 2; }
    C (*inst)(const char *, int, const char *, const char *, const Callbacks *, int, int) = (void *)GetProcAddress(h, "fmi2Instantiate");
    int (*setup)(C, int, double, double, int, double) = (void *)GetProcAddress(h, "fmi2SetupExperiment");
    int (*enter)(C) = (void *)GetProcAddress(h, "fmi2EnterInitializationMode");
    int (*exit_)(C) = (void *)GetProcAddress(h, "fmi2ExitInitializationMode");
    int (*step)(C, double, double, int) = (void *)GetProcAddress(h, "fmi2DoStep");
    int (*get)(C, const unsigned *, size_t, double *) = (void *)GetProcAddress(h, "fmi2GetReal");
    Callbacks cb = {lg, 0, 0, 0, 0};
    C c = inst("w", 1, argv[2], argv[3], &cb, 0, 0);
    if (!c) return 3;
    setup(c, 0, 0.0, 0.0, 0, 0.0); enter(c); exit_(c);
    int n = atoi(argv[4]); double hh = 1.0 / 256; unsigned vr[8] = {1000, 1001, 1002, 1003, 1004, 1005, 1006, 1007};
    double y[8];
    for (int k = 0; k < n; k++) {
        if (k) step(c, (k - 1) * hh, hh, 1);
        get(c, vr, 8, y);
        for (int j = 0; j < 8; j++) printf("%.17g%c", y[j], j == 7 ? '\n' : ' ');
    }
    return 0;
}
