/*
 * record.c - a host's recording loop for an FMI 2.0 co-simulation FMU (twin.fmu.run).
 *
 * Calls the FMU's own fmi2DoStep and fmi2GetReal (function pointers the caller took from the FMU's
 * binary) once per communication point and writes the outputs row by row, so a long record costs the
 * FMU's steps and no interpreter per step. Self-contained: the FMI 2.0 types are declared here as the
 * standard defines them on every platform the FMU runtime is built for.
 */
#include <stddef.h>

typedef void *fmi2Component;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Boolean;
typedef int fmi2Status; /* fmi2OK = 0, fmi2Warning = 1, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending */

typedef fmi2Status (*DoStep)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
typedef fmi2Status (*GetReal)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]);

/* Record samples k0 .. k0 + n - 1 at t0 + k h into out (rows of m; row 0 is sample k0): a step from
   sample k - 1 to k before each sample but the first of the run (k = 0). Returns the number of samples
   written; *status is the status of the call that stopped the loop (above fmi2Warning), or 0. */
long twin_record(void *do_step, void *get_real, fmi2Component c, double t0, double h, long k0, long n,
                 const fmi2ValueReference *vr, size_t m, double *out, int *status) {
    DoStep step = (DoStep)do_step;
    GetReal get = (GetReal)get_real;
    *status = 0;
    for (long i = 0; i < n; i++) {
        long k = k0 + i;
        fmi2Status st;
        if (k > 0 && (st = step(c, t0 + (double)(k - 1) * h, h, 1)) > 1) {
            *status = st;
            return i;
        }
        if ((st = get(c, vr, m, out + (size_t)i * m)) > 1) {
            *status = 10 + st; /* 10 + status: fmi2GetReal failed */
            return i;
        }
    }
    return n;
}
