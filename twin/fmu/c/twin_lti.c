/*
 * twin_lti.c - generic FMI 2.0 co-simulation runtime of a linear rotor model.
 *
 * The system x[k+1] = Phi x[k] + sum_j (G0_j f_j[k] + G1_j (f_j[k+1] - f_j[k])), y = C x
 * is read from resources/twin_lti.bin (written by twin.fmu.export). The step matrices
 * are exact (matrix exponential) for the nominal communication step, so a step costs
 * one dense mat-vec plus a few columns, and the binary does not depend on the model:
 * it is compiled once per platform and reused for every export.
 *
 * Force ports: external inputs are held constant over a step (zero-order hold);
 * the built-in 1X unbalance and runner turbulence are known ahead and use a
 * first-order hold. Random numbers: splitmix64 + Box-Muller (reproduced in
 * twin.fmu.excitation for the numpy reference).
 *
 * Steady start (parameter steady_start): at initialisation the state is the unbalance's periodic
 * state plus a draw from the turbulence response's stationary covariance (see twin.fmu.steady).
 *
 * FMU state: fmi2GetFMUstate copies everything a run depends on (time, state vector,
 * inputs, outputs, parameters, the random generators); fmi2SerializeFMUstate writes
 * that copy as bytes with a header naming the system's sizes, so a state is restored
 * bit for bit, in this instance or another of the same FMU.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define MAGIC "TWINLTI4"
#define VR_UNBALANCE_ME 1
#define VR_UNBALANCE_PHASE 2
#define VR_TURBULENCE_ASD 3
#define VR_NOISE_STD 4
#define VR_UNBALANCE_NODE 5
#define VR_TURBULENCE_SEED 6
#define VR_NOISE_SEED 7
#define VR_STEADY_START 8
/* the initial state's draws: a stream of their own, so the turbulence forces do not depend on them */
#define STEADY_STREAM 0xD1B54A32D192ED03ULL
#define VR_INPUT0 100
#define VR_OUTPUT0 1000
#define STEP_TOLERANCE 1e-6
#define TWO_PI 6.283185307179586476925286766559
#define STATE_MAGIC "TWINSTA1"

typedef struct {
    uint64_t state;
    int has_spare;
    double spare;
} Rng;

typedef struct {
    /* system */
    int n, p, m, n_in, turb_x, turb_y;
    double h, omega;
    int *in_port;
    double *phi, *g0t, *g1t, *c; /* g0t, g1t: p rows of n (transposed) */
    double *steady_f, *resp_re, *resp_im; /* steady start: n x n factor; p rows of n (transposed) */
    /* run state */
    double *x, *xn, *y, *u;
    double t, unb_me, unb_phase, turb_asd, noise_std;
    double start[4]; /* start values of unbalance_me, unbalance_phase, turbulence_asd, noise_std */
    int unb_node, turb_seed, noise_seed, steady, has_steady;
    double turb_now[2], turb_next[2];
    Rng turb_rng, noise_rng;
    int initialised, unb_node_start;
    fmi2CallbackFunctions cb;
    char name[128];
} Lti;

/* ---- random numbers: splitmix64 and Box-Muller ------------------------------------- */
static uint64_t splitmix64(uint64_t *s) {
    uint64_t z = (*s += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static double gauss(Rng *r) {
    if (r->has_spare) {
        r->has_spare = 0;
        return r->spare;
    }
    double u1 = ((double)(splitmix64(&r->state) >> 11) + 1.0) * 0x1.0p-53; /* (0, 1] */
    double u2 = (double)(splitmix64(&r->state) >> 11) * 0x1.0p-53;        /* [0, 1) */
    double rad = sqrt(-2.0 * log(u1));
    r->spare = rad * sin(TWO_PI * u2);
    r->has_spare = 1;
    return rad * cos(TWO_PI * u2);
}

static void rng_seed(Rng *r, int seed) {
    r->state = (uint64_t)(int64_t)seed;
    r->has_spare = 0;
}

/* ---- helpers ------------------------------------------------------------------------ */
/* The message is passed as the logger's format (its '%' doubled, no arguments): hosts that format it and
   hosts that print it as it is both show the text. */
static void logmsg(Lti *s, fmi2Status st, const char *msg) {
    if (!s || !s->cb.logger) return;
    char fmt[2048];
    size_t k = 0;
    for (const char *p = msg; *p && k + 2 < sizeof fmt; p++) {
        if (*p == '%') fmt[k++] = '%';
        fmt[k++] = *p;
    }
    fmt[k] = 0;
    s->cb.logger(s->cb.componentEnvironment, s->name, st, "twin", fmt);
}

/* Log why a call failed and return fmi2Error: every error the FMU returns says what was wrong. */
static fmi2Status fail(Lti *s, const char *fn, const char *what, long detail) {
    char msg[512];
    if (detail >= 0) snprintf(msg, sizeof msg, "%s: %s %ld", fn, what, detail);
    else snprintf(msg, sizeof msg, "%s: %s", fn, what);
    logmsg(s, fmi2Error, msg);
    return fmi2Error;
}

/* The values fmi2Instantiate leaves and fmi2Reset returns to: the modelDescription's start values. */
static void to_start_values(Lti *s) {
    s->initialised = 0;
    s->t = 0;
    s->unb_me = s->start[0];
    s->unb_phase = s->start[1];
    s->turb_asd = s->start[2];
    s->noise_std = s->start[3];
    s->unb_node = s->unb_node_start;
    s->turb_seed = 1;
    s->noise_seed = 2;
    s->steady = s->has_steady;
    memset(s->x, 0, (size_t)s->n * 8);
    memset(s->y, 0, (size_t)(s->m ? s->m : 1) * 8);
    memset(s->u, 0, (size_t)(s->n_in ? s->n_in : 1) * 8);
    s->turb_now[0] = s->turb_now[1] = s->turb_next[0] = s->turb_next[1] = 0.0;
}

static int read_block(FILE *f, void *dst, size_t size, size_t count) {
    return fread(dst, size, count, f) == count;
}

/* Percent-decode a file:// URI (FMI 2 resource location) into a path. */
static void uri_to_path(const char *uri, char *out, size_t len) {
    const char *p = uri;
    if (strncmp(p, "file://", 7) == 0) {
        p += 7;
        if (strncmp(p, "localhost/", 10) == 0) p += 9;
    } else if (strncmp(p, "file:", 5) == 0) {
        p += 5;
    }
    size_t k = 0;
    while (*p && k + 1 < len) {
        if (p[0] == '%' && p[1] && p[2]) {
            char hex[3] = {p[1], p[2], 0};
            out[k++] = (char)strtol(hex, NULL, 16);
            p += 3;
        } else {
            out[k++] = *p++;
        }
    }
    out[k] = 0;
}

/* y = Phi x with four independent partial sums per row (the plain loop is latency-bound). */
static void matvec(const double *a, const double *x, double *y, int rows, int cols) {
    for (int i = 0; i < rows; i++) {
        const double *row = a + (size_t)i * cols;
        double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
        int j = 0;
        for (; j + 3 < cols; j += 4) {
            s0 += row[j] * x[j];
            s1 += row[j + 1] * x[j + 1];
            s2 += row[j + 2] * x[j + 2];
            s3 += row[j + 3] * x[j + 3];
        }
        for (; j < cols; j++) s0 += row[j] * x[j];
        y[i] = (s0 + s1) + (s2 + s3);
    }
}

static void axpy(double a, const double *v, double *y, int n) {
    if (a == 0.0) return;
    for (int i = 0; i < n; i++) y[i] += a * v[i];
}

static void update_outputs(Lti *s) {
    matvec(s->c, s->x, s->y, s->m, s->n);
    if (s->noise_std > 0)
        for (int i = 0; i < s->m; i++) s->y[i] += s->noise_std * gauss(&s->noise_rng);
}

static void draw_turbulence(Lti *s, double *f) {
    /* ZOH-equivalent white noise of one-sided amplitude spectral density asd: std = asd / sqrt(2 h) */
    double sd = s->turb_asd / sqrt(2.0 * s->h);
    f[0] = sd * gauss(&s->turb_rng);
    f[1] = sd * gauss(&s->turb_rng);
}

static void free_lti(Lti *s) {
    if (!s) return;
    free(s->in_port); free(s->phi); free(s->g0t); free(s->g1t); free(s->c);
    free(s->steady_f); free(s->resp_re); free(s->resp_im);
    free(s->x); free(s->xn); free(s->y); free(s->u);
    free(s);
}

/* ---- FMI 2.0 ------------------------------------------------------------------------ */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) {
    (void)c; (void)on; (void)n; (void)cat; /* the FMU logs errors only, and always: nothing to switch */
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean logging) {
    (void)visible; (void)logging;
    Lti *s = calloc(1, sizeof(Lti));
    if (!s) return NULL;
    if (functions) s->cb = *functions;
    snprintf(s->name, sizeof s->name, "%s", name ? name : "twin");
    if (type != fmi2CoSimulation) {
        logmsg(s, fmi2Error, "this FMU supports co-simulation only");
        free_lti(s);
        return NULL;
    }
    char path[4096], file[4200];
    uri_to_path(resources ? resources : "", path, sizeof path);
    size_t len = strlen(path);
    snprintf(file, sizeof file, "%s%stwin_lti.bin", path, (len && path[len - 1] == '/') ? "" : "/");
    FILE *f = fopen(file, "rb");
    if (!f) {
        char msg[4400];
        snprintf(msg, sizeof msg, "cannot open resource file %s", file);
        logmsg(s, fmi2Error, msg);
        free_lti(s);
        return NULL;
    }
    char magic[8], fguid[64];
    int32_t dims[8];
    double hw[6];
    int ok = read_block(f, magic, 1, 8);
    if (ok && memcmp(magic, MAGIC, 8) != 0) {
        fclose(f);
        logmsg(s, fmi2Error, "resource file twin_lti.bin has another format than this runtime's (" MAGIC
                             "): the FMU mixes files of two twin versions; export it again");
        free_lti(s);
        return NULL;
    }
    ok = ok && read_block(f, dims, 4, 8) && read_block(f, hw, 8, 6) && read_block(f, fguid, 1, 64);
    if (ok) {
        s->n = dims[0]; s->p = dims[1]; s->m = dims[2]; s->n_in = dims[3]; s->turb_x = dims[4]; s->turb_y = dims[5];
        s->unb_node_start = dims[6]; /* start value of the unbalance_node parameter */
        s->has_steady = dims[7];
        s->h = hw[0]; s->omega = hw[1];
        for (int k = 0; k < 4; k++) s->start[k] = hw[2 + k];
        size_t n = s->n, p = s->p, m = s->m;
        s->in_port = calloc(s->n_in ? s->n_in : 1, sizeof(int));
        s->phi = malloc(n * n * 8); s->g0t = malloc(p * n * 8); s->g1t = malloc(p * n * 8);
        s->c = malloc(m * n * 8);
        size_t ns = s->has_steady ? n : 0; /* the steady start's matrices, when exported */
        s->steady_f = malloc(ns * n * 8 + 8); s->resp_re = malloc(ns ? p * n * 8 : 8);
        s->resp_im = malloc(ns ? p * n * 8 : 8);
        s->x = calloc(n, 8); s->xn = calloc(n, 8); s->y = calloc(m ? m : 1, 8); s->u = calloc(s->n_in ? s->n_in : 1, 8);
        int32_t *tmp = calloc(s->n_in ? s->n_in : 1, 4);
        ok = s->phi && s->g0t && s->g1t && s->c && s->x && s->xn && s->y && s->u && tmp &&
             read_block(f, tmp, 4, s->n_in) && read_block(f, s->phi, 8, n * n) && read_block(f, s->g0t, 8, p * n) &&
             read_block(f, s->g1t, 8, p * n) && read_block(f, s->c, 8, m * n) && s->steady_f && s->resp_re &&
             s->resp_im && (!ns || (read_block(f, s->steady_f, 8, n * n) && read_block(f, s->resp_re, 8, p * n) &&
                                     read_block(f, s->resp_im, 8, p * n)));
        for (int i = 0; ok && i < s->n_in; i++) {
            s->in_port[i] = tmp[i];
            if (tmp[i] < 0 || tmp[i] >= s->p) ok = 0;
        }
        free(tmp);
    }
    fclose(f);
    if (!ok) {
        logmsg(s, fmi2Error, "resource file twin_lti.bin is corrupt or truncated");
        free_lti(s);
        return NULL;
    }
    fguid[63] = 0;
    if (!guid || strcmp(guid, fguid) != 0) {
        logmsg(s, fmi2Error, "GUID of modelDescription.xml does not match the resource file");
        free_lti(s);
        return NULL;
    }
    to_start_values(s);
    return s;
}

void fmi2FreeInstance(fmi2Component c) { free_lti((Lti *)c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDefined, fmi2Real stop) {
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stop;
    ((Lti *)c)->t = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }

/* The stationary state at the start time (see twin.fmu.steady): the unbalance's periodic state, the
   turbulence response drawn from its stationary law, and the first-order hold's share of the first force. */
static void steady_state(Lti *s) {
    int n = s->n;
    if (s->unb_me != 0.0) {
        double a = s->unb_me * s->omega * s->omega, ph = s->unb_phase + s->omega * s->t;
        double cr = a * cos(ph), ci = a * sin(ph);
        size_t cx = (size_t)(2 * s->unb_node) * n, cy = cx + n;
        for (int i = 0; i < n; i++) /* Re(R_x c) + Re(R_y (-i c)) */
            s->x[i] += s->resp_re[cx + i] * cr - s->resp_im[cx + i] * ci + s->resp_re[cy + i] * ci +
                       s->resp_im[cy + i] * cr;
    }
    if (s->turb_x >= 0 && s->turb_asd > 0) {
        Rng r = {(uint64_t)(int64_t)s->turb_seed ^ STEADY_STREAM, 0, 0.0};
        double *g = s->xn; /* scratch */
        for (int i = 0; i < n; i++) g[i] = s->turb_asd * gauss(&r);
        for (int i = 0; i < n; i++) {
            const double *row = s->steady_f + (size_t)i * n;
            double acc = 0.0;
            for (int j = 0; j < n; j++) acc += row[j] * g[j];
            s->x[i] += acc;
        }
        axpy(s->turb_now[0], s->g1t + (size_t)s->turb_x * n, s->x, n);
        axpy(s->turb_now[1], s->g1t + (size_t)s->turb_y * n, s->x, n);
    }
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Lti *s = (Lti *)c;
    if (s->unb_node < 0 || 2 * s->unb_node + 1 >= s->p) {
        logmsg(s, fmi2Error, "unbalance_node is not a node of the model");
        return fmi2Error;
    }
    rng_seed(&s->turb_rng, s->turb_seed);
    rng_seed(&s->noise_rng, s->noise_seed);
    memset(s->x, 0, (size_t)s->n * 8);
    s->turb_now[0] = s->turb_now[1] = 0.0;
    if (s->turb_x >= 0 && s->turb_asd > 0) draw_turbulence(s, s->turb_now);
    if (s->steady) steady_state(s);
    update_outputs(s);
    s->initialised = 1;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2Reset(fmi2Component c) {
    to_start_values((Lti *)c);
    return fmi2OK;
}

static void unbalance(const Lti *s, double t, double *f) {
    double a = s->unb_me * s->omega * s->omega, ph = s->omega * t + s->unb_phase;
    f[0] = a * cos(ph);
    f[1] = a * sin(ph);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    (void)noSetPrior;
    Lti *s = (Lti *)c;
    if (!s->initialised) return fail(s, "fmi2DoStep", "called before fmi2ExitInitializationMode", -1);
    if (fabs(h - s->h) > STEP_TOLERANCE * s->h) {
        char msg[256];
        snprintf(msg, sizeof msg, "communication step %.12g s differs from the exported step %.12g s; export the FMU for this step", h, s->h);
        logmsg(s, fmi2Error, msg);
        return fmi2Error;
    }
    int n = s->n;
    matvec(s->phi, s->x, s->xn, n, n);
    for (int i = 0; i < s->n_in; i++) axpy(s->u[i], s->g0t + (size_t)s->in_port[i] * n, s->xn, n);
    if (s->unb_me != 0.0) {
        double f0[2], f1[2];
        unbalance(s, t, f0);
        unbalance(s, t + h, f1);
        for (int d = 0; d < 2; d++) {
            size_t col = (size_t)(2 * s->unb_node + d) * n;
            axpy(f0[d], s->g0t + col, s->xn, n);
            axpy(f1[d] - f0[d], s->g1t + col, s->xn, n);
        }
    }
    if (s->turb_x >= 0 && s->turb_asd > 0) {
        draw_turbulence(s, s->turb_next);
        int ports[2] = {s->turb_x, s->turb_y};
        for (int d = 0; d < 2; d++) {
            size_t col = (size_t)ports[d] * n;
            axpy(s->turb_now[d], s->g0t + col, s->xn, n);
            axpy(s->turb_next[d] - s->turb_now[d], s->g1t + col, s->xn, n);
        }
        s->turb_now[0] = s->turb_next[0];
        s->turb_now[1] = s->turb_next[1];
    }
    double *tmp = s->x; s->x = s->xn; s->xn = tmp;
    s->t = t + h;
    update_outputs(s);
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return fail((Lti *)c, "fmi2CancelStep", "steps are synchronous: there is none to cancel", -1);
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Lti *s = (Lti *)c;
    for (size_t i = 0; i < nvr; i++) {
        fmi2ValueReference r = vr[i];
        if (r >= VR_OUTPUT0 && r < VR_OUTPUT0 + (unsigned)s->m) value[i] = s->y[r - VR_OUTPUT0];
        else if (r >= VR_INPUT0 && r < VR_INPUT0 + (unsigned)s->n_in) value[i] = s->u[r - VR_INPUT0];
        else if (r == VR_UNBALANCE_ME) value[i] = s->unb_me;
        else if (r == VR_UNBALANCE_PHASE) value[i] = s->unb_phase;
        else if (r == VR_TURBULENCE_ASD) value[i] = s->turb_asd;
        else if (r == VR_NOISE_STD) value[i] = s->noise_std;
        else return fail(s, "fmi2GetReal", "no Real variable has value reference", (long)r);
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Lti *s = (Lti *)c;
    for (size_t i = 0; i < nvr; i++) {
        fmi2ValueReference r = vr[i];
        if (r >= VR_INPUT0 && r < VR_INPUT0 + (unsigned)s->n_in) s->u[r - VR_INPUT0] = value[i];
        else if (r != VR_UNBALANCE_ME && r != VR_UNBALANCE_PHASE && r != VR_TURBULENCE_ASD && r != VR_NOISE_STD)
            return fail(s, "fmi2SetReal", "no Real input or parameter has value reference", (long)r);
        else if (s->initialised) /* fixed parameters */
            return fail(s, "fmi2SetReal", "parameters are fixed after initialisation; value reference", (long)r);
        else if (r == VR_UNBALANCE_ME) s->unb_me = value[i];
        else if (r == VR_UNBALANCE_PHASE) s->unb_phase = value[i];
        else if (r == VR_TURBULENCE_ASD) s->turb_asd = value[i];
        else s->noise_std = value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    Lti *s = (Lti *)c;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] == VR_UNBALANCE_NODE) value[i] = s->unb_node;
        else if (vr[i] == VR_TURBULENCE_SEED) value[i] = s->turb_seed;
        else if (vr[i] == VR_NOISE_SEED) value[i] = s->noise_seed;
        else return fail(s, "fmi2GetInteger", "no Integer variable has value reference", (long)vr[i]);
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    Lti *s = (Lti *)c;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != VR_UNBALANCE_NODE && vr[i] != VR_TURBULENCE_SEED && vr[i] != VR_NOISE_SEED)
            return fail(s, "fmi2SetInteger", "no Integer parameter has value reference", (long)vr[i]);
        if (s->initialised)
            return fail(s, "fmi2SetInteger", "parameters are fixed after initialisation; value reference", (long)vr[i]);
        if (vr[i] == VR_UNBALANCE_NODE) s->unb_node = value[i];
        else if (vr[i] == VR_TURBULENCE_SEED) s->turb_seed = value[i];
        else s->noise_seed = value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean v[]) {
    Lti *s = (Lti *)c;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] == VR_STEADY_START) v[i] = s->steady ? fmi2True : fmi2False;
        else return fail(s, "fmi2GetBoolean", "no Boolean variable has value reference", (long)vr[i]);
    }
    return fmi2OK;
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean v[]) {
    Lti *s = (Lti *)c;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != VR_STEADY_START)
            return fail(s, "fmi2SetBoolean", "no Boolean parameter has value reference", (long)vr[i]);
        if (s->initialised)
            return fail(s, "fmi2SetBoolean", "parameters are fixed after initialisation; value reference", (long)vr[i]);
        if (v[i] && !s->has_steady)
            return fail(s, "fmi2SetBoolean", "steady_start: this FMU was exported without a steady start", -1);
        s->steady = v[i] ? 1 : 0;
    }
    return fmi2OK;
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String v[]) {
    (void)v;
    return nvr ? fail((Lti *)c, "fmi2GetString", "the FMU has no String variables; value reference", (long)vr[0]) : fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String v[]) {
    (void)v;
    return nvr ? fail((Lti *)c, "fmi2SetString", "the FMU has no String variables; value reference", (long)vr[0]) : fmi2OK;
}

/* ---- FMU state ----------------------------------------------------------------------- */
typedef struct {
    double t, unb_me, unb_phase, turb_asd, noise_std, turb_now[2], turb_next[2];
    int unb_node, turb_seed, noise_seed, initialised, steady;
    Rng turb_rng, noise_rng;
    double *x, *y, *u;
} Snapshot;

static void free_snapshot(Snapshot *q) {
    if (!q) return;
    free(q->x); free(q->y); free(q->u);
    free(q);
}

/* The run state's fields, of the same name and type in Lti and Snapshot: one list for both directions. */
#define RUN_STATE(X) X(t) X(unb_me) X(unb_phase) X(turb_asd) X(noise_std) X(turb_now) X(turb_next) \
    X(unb_node) X(turb_seed) X(noise_seed) X(initialised) X(steady) X(turb_rng) X(noise_rng)
#define COPY_FIELD(f)                                                                        \
    {                                                                                        \
        _Static_assert(sizeof dst->f == sizeof src->f, "run-state field " #f " differs in size"); \
        memcpy(&dst->f, &src->f, sizeof dst->f);                                             \
    }

/* Copy the state vector, outputs and inputs (sizes of the system s). */
static void copy_vectors(const Lti *s, double *x, double *y, double *u, const double *fx, const double *fy,
                         const double *fu) {
    memcpy(x, fx, (size_t)s->n * 8);
    memcpy(y, fy, (size_t)(s->m ? s->m : 1) * 8);
    memcpy(u, fu, (size_t)(s->n_in ? s->n_in : 1) * 8);
}

static void take(const Lti *src, Snapshot *dst) {
    RUN_STATE(COPY_FIELD)
    copy_vectors(src, dst->x, dst->y, dst->u, src->x, src->y, src->u);
}

static void give(Lti *dst, const Snapshot *src) {
    RUN_STATE(COPY_FIELD)
    copy_vectors(dst, dst->x, dst->y, dst->u, src->x, src->y, src->u);
}

static Snapshot *new_snapshot(const Lti *s) {
    Snapshot *q = calloc(1, sizeof(Snapshot));
    if (!q) return NULL;
    q->x = malloc((size_t)s->n * 8);
    q->y = malloc((size_t)(s->m ? s->m : 1) * 8);
    q->u = malloc((size_t)(s->n_in ? s->n_in : 1) * 8);
    if (!q->x || !q->y || !q->u) {
        free_snapshot(q);
        return NULL;
    }
    return q;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st) {
    Lti *s = (Lti *)c;
    if (!st) return fail(s, "fmi2GetFMUstate", "no place to put the state (NULL pointer)", -1);
    Snapshot *q = (Snapshot *)*st;
    if (!q) {
        q = new_snapshot(s);
        if (!q) return fail(s, "fmi2GetFMUstate", "out of memory", -1);
    }
    take(s, q);
    *st = q;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) {
    Lti *s = (Lti *)c;
    if (!st) return fail(s, "fmi2SetFMUstate", "no state given (NULL)", -1);
    give(s, (const Snapshot *)st);
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *st) {
    (void)c;
    if (st) {
        free_snapshot((Snapshot *)*st);
        *st = NULL;
    }
    return fmi2OK;
}

/* Bytes: magic, int32 n, m, n_in, unb_node, seeds, initialised, rng has_spare x2, steady, uint64 rng states x2,
   doubles t, parameters (4), turbulence (4), rng spares (2), x, y, u. */
static size_t state_bytes(const Lti *s) {
    return 8 + 4 * 10 + 8 * 2 + 8 * (1 + 4 + 4 + 2) + 8 * ((size_t)s->n + (size_t)s->m + (size_t)s->n_in);
}

static void put(fmi2Byte **p, const void *v, size_t size) { memcpy(*p, v, size); *p += size; }
static void get(const fmi2Byte **p, void *v, size_t size) { memcpy(v, *p, size); *p += size; }

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate st, size_t *n) {
    (void)st;
    *n = state_bytes((Lti *)c);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate st, fmi2Byte b[], size_t n) {
    Lti *s = (Lti *)c;
    const Snapshot *q = (const Snapshot *)st;
    if (!q) return fail(s, "fmi2SerializeFMUstate", "no state given (NULL)", -1);
    if (n < state_bytes(s)) return fail(s, "fmi2SerializeFMUstate", "buffer too small; bytes needed:", (long)state_bytes(s));
    fmi2Byte *p = b;
    int32_t ints[10] = {s->n, s->m, s->n_in, q->unb_node, q->turb_seed, q->noise_seed, q->initialised,
                        q->turb_rng.has_spare, q->noise_rng.has_spare, q->steady};
    double d[11] = {q->t, q->unb_me, q->unb_phase, q->turb_asd, q->noise_std, q->turb_now[0], q->turb_now[1],
                    q->turb_next[0], q->turb_next[1], q->turb_rng.spare, q->noise_rng.spare};
    put(&p, STATE_MAGIC, 8);
    put(&p, ints, sizeof ints);
    put(&p, &q->turb_rng.state, 8);
    put(&p, &q->noise_rng.state, 8);
    put(&p, d, sizeof d);
    put(&p, q->x, (size_t)s->n * 8);
    put(&p, q->y, (size_t)s->m * 8);
    put(&p, q->u, (size_t)s->n_in * 8);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *st) {
    Lti *s = (Lti *)c;
    if (!st) return fail(s, "fmi2DeSerializeFMUstate", "no place to put the state (NULL pointer)", -1);
    if (n != state_bytes(s) || memcmp(b, STATE_MAGIC, 8) != 0)
        return fail(s, "fmi2DeSerializeFMUstate", "not a state of this FMU; bytes given:", (long)n);
    const fmi2Byte *p = b + 8;
    int32_t ints[10];
    double d[11];
    get(&p, ints, sizeof ints);
    if (ints[0] != s->n || ints[1] != s->m || ints[2] != s->n_in)
        return fail(s, "fmi2DeSerializeFMUstate", "a state of another system; its state size:", (long)ints[0]);
    Snapshot *q = new_snapshot(s);
    if (!q) return fail(s, "fmi2DeSerializeFMUstate", "out of memory", -1);
    q->unb_node = ints[3]; q->turb_seed = ints[4]; q->noise_seed = ints[5]; q->initialised = ints[6];
    q->turb_rng.has_spare = ints[7]; q->noise_rng.has_spare = ints[8]; q->steady = ints[9];
    get(&p, &q->turb_rng.state, 8);
    get(&p, &q->noise_rng.state, 8);
    get(&p, d, sizeof d);
    q->t = d[0]; q->unb_me = d[1]; q->unb_phase = d[2]; q->turb_asd = d[3]; q->noise_std = d[4];
    q->turb_now[0] = d[5]; q->turb_now[1] = d[6]; q->turb_next[0] = d[7]; q->turb_next[1] = d[8];
    q->turb_rng.spare = d[9]; q->noise_rng.spare = d[10];
    get(&p, q->x, (size_t)s->n * 8);
    get(&p, q->y, (size_t)s->m * 8);
    get(&p, q->u, (size_t)s->n_in * 8);
    if (*st) free_snapshot((Snapshot *)*st);
    *st = q;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return fail((Lti *)c, "fmi2GetDirectionalDerivative", "not provided by this FMU", -1);
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    return fail((Lti *)c, "fmi2SetRealInputDerivatives", "inputs are held over a step; no derivatives", -1);
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    return fail((Lti *)c, "fmi2GetRealOutputDerivatives", "not provided by this FMU", -1);
}
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    Lti *s = (Lti *)c;
    if (k == fmi2LastSuccessfulTime) { *v = s->t; return fmi2OK; }
    return fmi2Discard;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
