/*
 * twin_core.c - the model core of the FMU runtime (twin_lti.c): a linear rotor model in its modal form.
 *
 * The system is stepped in its modal (diagonal) form, read from resources/twin_lti.bin (written by
 * twin.fmu.export; see twin.fmu.modal): one complex first-order system per pole,
 *     z_i' = lambda_i z_i + wb_i . f(t),   y = Re(sum_i cv_i z_i).
 * A step of any length is exact: z <- a z + g0 wb.f(t) + g1 wb.(f(t+h) - f(t)) with a = exp(lambda h),
 * g0 = h phi1(lambda h), g1 = h phi2(lambda h), computed once per step length and cached. A step costs
 * O(n) rather than a dense n x n product, and the binary does not depend on the model: it is compiled
 * once per platform and reused for every export.
 *
 * Forces: external inputs are held constant over a step (zero-order hold). The built-in excitation, the
 * 1X unbalance and the runner turbulence, is a force linear between samples on a fixed grid, the
 * exported step h0 from the start time; a communication step that does not end on the grid is split
 * at its grid points, so the trajectory does not depend on the steps the host takes. Random numbers:
 * splitmix64 + Box-Muller, addressed by sample index (turbulence sample j uses the generator's outputs
 * 2j+1 and 2j+2; sensor noise sample j, channel c, normal number j m + c), reproduced in
 * twin.fmu.excitation for the numpy reference. The sensor noise is constant between grid points.
 *
 * Steady start (parameter steady_start): at initialisation the state is the unbalance's periodic
 * state plus a draw from the turbulence response's stationary covariance (see twin.fmu.steady).
 *
 * FMU state: a snapshot copies everything a run depends on (time, modal state, inputs, outputs,
 * parameters); its serialization writes that copy as bytes with a header naming the system's sizes, so a
 * state is restored bit for bit, in this instance or another of the same FMU.
 *
 * Everything here is static and knows no FMI header: twin_fmi2.c and twin_fmi3.c are the APIs on it, and
 * twin_lti.c compiles the three as one translation unit.
 */
#include <complex.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>


#define MAGIC "TWINLTI5"
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
#define VR_TIME 0 /* the independent variable (FMI 3.0) */
#define VR_INPUT0 100
#define VR_OUTPUT0 1000
#define VR_STATE0 100000 /* the continuous states: Re z_i at 2i, Im z_i at 2i + 1 */
#define VR_DER0 200000   /* their derivatives */
#define GRID_SNAP 1e-9 /* a time within this many grid steps of a grid point is on it */
#define SERIES_BELOW 0.1 /* |lambda h| below which phi1, phi2 are summed from their series */
#define N_CACHE 4       /* step lengths whose coefficients are kept */
#define TWO_PI 6.283185307179586476925286766559
#define STATE_MAGIC "TWINSTA2"

typedef double complex cplx;

typedef struct {
    int port[4]; /* unbalance x, y, turbulence x, y (-1: none) */
    double f[4];
} Forces;

typedef struct {
    double h; /* step length [s], 0 = empty */
    cplx *a, *g0, *g1;
} Coefs;

typedef struct {
    /* system */
    int r, n, p, m, n_in, turb_x, turb_y;
    double h0, omega;
    int *in_port;
    cplx *lam, *wbt, *cv; /* wbt: p rows of r (port-major); cv: m rows of r */
    cplx *steady_f;       /* steady start: r rows of n */
    Coefs cache[N_CACHE];
    int next_slot;
    /* run state */
    cplx *z;
    double *y, *u, *scratch; /* scratch: 2 r doubles (or m for the noise) */
    double *zeros;           /* 2 r zeros */
    Forces sample[2];        /* the last two grid samples of the built-in forces */
    int64_t sample_j[2];
    int sample_ok[2];
    double t0, pos; /* start time (the grid's origin) and time in grid steps from it */
    double unb_me, unb_phase, turb_asd, noise_std;
    double start[4]; /* start values of unbalance_me, unbalance_phase, turbulence_asd, noise_std */
    int unb_node, turb_seed, noise_seed, steady, has_steady;
    int initialised, unb_node_start;
    int model_exchange; /* instantiated for model exchange: the host integrates dz/dt */
    double *der;        /* dz/dt at the current time and state (model exchange), 2 r doubles */
    int fmi_version;    /* of the API that instantiated it: how to call its logger */
    void *env;          /* the host's environment pointer, passed back to its logger */
    void (*logger)(void);
    char name[128];
} Lti;

static void forget_samples(Lti *s) { s->sample_ok[0] = s->sample_ok[1] = 0; }

/* ---- random numbers: splitmix64 and Box-Muller, addressed by index ------------------------ */
static uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

/* The pair of standard normals made from the generator's outputs 2j+1 and 2j+2 (cos, sin). */
static void gauss_pair(uint64_t seed, uint64_t j, double *c, double *s) {
    uint64_t base = seed + (2 * j) * 0x9E3779B97F4A7C15ULL;
    double u1 = ((double)(mix64(base + 0x9E3779B97F4A7C15ULL) >> 11) + 1.0) * 0x1.0p-53; /* (0, 1] */
    double u2 = (double)(mix64(base + 2 * 0x9E3779B97F4A7C15ULL) >> 11) * 0x1.0p-53;     /* [0, 1) */
    double rad = sqrt(-2.0 * log(u1));
    *c = rad * cos(TWO_PI * u2);
    *s = rad * sin(TWO_PI * u2);
}

/* count consecutive standard normals of a seed's stream from number q0 on, one Box-Muller pair per two. */
static void gauss_run(uint64_t seed, uint64_t q0, int count, double *out) {
    for (int k = 0; k < count;) {
        uint64_t q = q0 + (uint64_t)k;
        double c, s;
        gauss_pair(seed, q / 2, &c, &s);
        if (q % 2 == 0) out[k++] = c;
        if (k < count) out[k++] = s;
    }
}

static uint64_t seed_of(int seed) { return (uint64_t)(int64_t)seed; }

/* ---- helpers ------------------------------------------------------------------------ */
/* The host's loggers, as FMI 2.0 and FMI 3.0 declare them (statuses are numbered alike in both). */
typedef void (*Log2)(void *env, const char *instance, int status, const char *category, const char *message, ...);
typedef void (*Log3)(void *env, int status, const char *category, const char *message);
#define TWIN_OK 0
#define TWIN_DISCARD 2
#define TWIN_ERROR 3

/* Log a message. FMI 2.0 passes it as the logger's format (its '%' doubled, no arguments), so hosts that
   format it and hosts that print it as it is both show the text; FMI 3.0 passes the text itself. */
static void logmsg(Lti *s, int st, const char *msg) {
    if (!s || !s->logger) return;
    if (s->fmi_version == 3) {
        ((Log3)s->logger)(s->env, st, "logStatusError", msg);
        return;
    }
    char fmt[2048];
    size_t k = 0;
    for (const char *p = msg; *p && k + 2 < sizeof fmt; p++) {
        if (*p == '%') fmt[k++] = '%';
        fmt[k++] = *p;
    }
    fmt[k] = 0;
    ((Log2)s->logger)(s->env, s->name, st, "twin", fmt);
}

/* Log why a call failed and return the error status: every error the FMU returns says what was wrong. */
static int fail(Lti *s, const char *fn, const char *what, long detail) {
    char msg[512];
    if (detail >= 0) snprintf(msg, sizeof msg, "%s: %s %ld", fn, what, detail);
    else snprintf(msg, sizeof msg, "%s: %s", fn, what);
    logmsg(s, TWIN_ERROR, msg);
    return TWIN_ERROR;
}

/* The values instantiation leaves and a reset returns to: the modelDescription's start values. */
static void to_start_values(Lti *s) {
    s->initialised = 0;
    s->t0 = 0;
    s->pos = 0;
    s->unb_me = s->start[0];
    s->unb_phase = s->start[1];
    s->turb_asd = s->start[2];
    s->noise_std = s->start[3];
    s->unb_node = s->unb_node_start;
    s->turb_seed = 1;
    s->noise_seed = 2;
    s->steady = s->has_steady;
    forget_samples(s);
    memset(s->z, 0, (size_t)s->r * sizeof(cplx));
    memset(s->y, 0, (size_t)(s->m ? s->m : 1) * 8);
    memset(s->u, 0, (size_t)(s->n_in ? s->n_in : 1) * 8);
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
#ifdef _WIN32
    if (p[0] == '/' && p[1] && p[2] == ':') p++; /* file:///C:/... is the path C:/... */
#endif
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

/* ---- exact step coefficients ---------------------------------------------------------- */
/* phi1(x) = (e^x - 1)/x and phi2(x) = (e^x - 1 - x)/x^2 (as twin.fmu.modal._phi12). */
static void phi12(cplx x, cplx *p1, cplx *p2) {
    if (cabs(x) < SERIES_BELOW) {
        cplx term = 1.0, s1 = 0.0, s2 = 0.0;
        for (int k = 0; k < 16; k++) {
            s1 += term / (k + 1);
            s2 += term / ((k + 1) * (k + 2));
            term = term * x / (k + 1);
        }
        *p1 = s1;
        *p2 = s2;
    } else {
        cplx e = cexp(x);
        *p1 = (e - 1.0) / x;
        *p2 = (e - 1.0 - x) / (x * x);
    }
}

/* The coefficients for a step of length h, from the cache or computed into its oldest slot. */
static const Coefs *coefs(Lti *s, double h) {
    for (int k = 0; k < N_CACHE; k++)
        if (s->cache[k].h == h) return &s->cache[k];
    int k = s->next_slot;
    s->next_slot = (k + 1) % N_CACHE == 0 ? 1 : (k + 1) % N_CACHE; /* slot 0 keeps the grid step */
    Coefs *c = &s->cache[k];
    for (int i = 0; i < s->r; i++) {
        cplx x = s->lam[i] * h, p1, p2;
        phi12(x, &p1, &p2);
        c->a[i] = cexp(x);
        c->g0[i] = h * p1;
        c->g1[i] = h * p2;
    }
    c->h = h;
    return c;
}

/* ---- the built-in excitation on its grid --------------------------------------------- */
/* The built-in forces at grid sample j (time t0 + j h0): unbalance, then turbulence, by port. */
static void grid_forces(const Lti *s, int64_t j, Forces *out) {
    double t = s->t0 + (double)j * s->h0;
    double a = s->unb_me * s->omega * s->omega, ph = s->omega * t + s->unb_phase;
    out->port[0] = 2 * s->unb_node;
    out->port[1] = 2 * s->unb_node + 1;
    out->f[0] = a * cos(ph);
    out->f[1] = a * sin(ph);
    out->port[2] = s->turb_x;
    out->port[3] = s->turb_y;
    out->f[2] = out->f[3] = 0.0;
    if (s->turb_x >= 0 && s->turb_asd > 0) {
        /* white noise of one-sided amplitude spectral density asd: std = asd / sqrt(2 h0) */
        double sd = s->turb_asd / sqrt(2.0 * s->h0);
        gauss_pair(seed_of(s->turb_seed), (uint64_t)j, &out->f[2], &out->f[3]);
        out->f[2] *= sd;
        out->f[3] *= sd;
    }
}

/* The built-in forces at grid samples j and j + 1, from a cache of two samples (derived from the run
   state: emptied whenever the parameters or the state are set); neither lookup evicts the other. */
static void grid_pair(Lti *s, int64_t j, const Forces **f0, const Forces **f1) {
    int slot[2] = {-1, -1};
    for (int q = 0; q < 2; q++)
        for (int k = 0; k < 2; k++)
            if (s->sample_ok[k] && s->sample_j[k] == j + q) slot[q] = k;
    for (int q = 0; q < 2; q++) {
        if (slot[q] >= 0) continue;
        int k = slot[1 - q] >= 0 ? 1 - slot[1 - q] : q; /* the slot the other sample does not hold */
        grid_forces(s, j + q, &s->sample[k]);
        s->sample_j[k] = j + q;
        s->sample_ok[k] = 1;
        slot[q] = k;
    }
    *f0 = &s->sample[slot[0]];
    *f1 = &s->sample[slot[1]];
}

/* d += wb . f for n_f forces by port (re, im pairs of the modal forcing, one per mode). */
static void add_modal_force(const Lti *s, const int *port, const double *f, int n_f, double *d) {
    for (int q = 0; q < n_f; q++) {
        if (port[q] < 0 || f[q] == 0.0) continue;
        const double *w = (const double *)(s->wbt + (size_t)port[q] * s->r);
        double v = f[q];
        for (int i = 0; i < 2 * s->r; i++) d[i] += w[i] * v;
    }
}

/* The modal forcing wb_i . f of forces given by port, for one mode (initialisation only). */
static cplx modal_force(const Lti *s, int i, const int *port, const double *f, int n_f) {
    cplx acc = 0.0;
    for (int q = 0; q < n_f; q++)
        if (port[q] >= 0 && f[q] != 0.0) acc += s->wbt[(size_t)port[q] * s->r + i] * f[q];
    return acc;
}

/* Advance the modal state over [pa, pb] (grid units, one grid interval j <= pa < pb <= j + 1): the
   built-in forces are linear between the grid samples j and j + 1, the inputs constant. Complex
   products are written out in real arithmetic (no C99 complex multiplication, which checks for
   infinities on every product). */
static void advance_piece(Lti *s, int64_t j, double pa, double pb) {
    const Coefs *c = coefs(s, (pb - pa) * s->h0);
    const Forces *f0, *f1;
    grid_pair(s, j, &f0, &f1);
    double wa = pa - (double)j, wb = pb - (double)j;
    double fa[4], df[4];
    for (int q = 0; q < 4; q++) {
        double slope = f1->f[q] - f0->f[q];
        fa[q] = f0->f[q] + wa * slope;
        df[q] = (wb - wa) * slope;
    }
    int r2 = 2 * s->r;
    /* the rows of wb for the four built-in force ports (a row of zeros where there is none) */
    const double *w[4];
    for (int q = 0; q < 4; q++) {
        int port = f0->port[q];
        if (port < 0 || (fa[q] == 0.0 && df[q] == 0.0)) port = -1;
        w[q] = port < 0 ? s->zeros : (const double *)(s->wbt + (size_t)port * s->r);
    }
    double *du = s->scratch;
    if (s->n_in) {
        memset(du, 0, (size_t)r2 * 8);
        add_modal_force(s, s->in_port, s->u, s->n_in, du);
    }
    const double *a = (const double *)c->a, *g0 = (const double *)c->g0, *g1 = (const double *)c->g1;
    double *z = (double *)s->z;
    for (int i = 0; i < r2; i += 2) {
        double d0r = w[0][i] * fa[0] + w[1][i] * fa[1] + w[2][i] * fa[2] + w[3][i] * fa[3];
        double d0i = w[0][i + 1] * fa[0] + w[1][i + 1] * fa[1] + w[2][i + 1] * fa[2] + w[3][i + 1] * fa[3];
        double d1r = w[0][i] * df[0] + w[1][i] * df[1] + w[2][i] * df[2] + w[3][i] * df[3];
        double d1i = w[0][i + 1] * df[0] + w[1][i + 1] * df[1] + w[2][i + 1] * df[2] + w[3][i + 1] * df[3];
        if (s->n_in) {
            d0r += du[i];
            d0i += du[i + 1];
        }
        double zr = z[i], zi = z[i + 1];
        z[i] = a[i] * zr - a[i + 1] * zi + g0[i] * d0r - g0[i + 1] * d0i + g1[i] * d1r - g1[i + 1] * d1i;
        z[i + 1] = a[i] * zi + a[i + 1] * zr + g0[i] * d0i + g0[i + 1] * d0r + g1[i] * d1i + g1[i + 1] * d1r;
    }
}

static double snap(double pos) {
    double k = floor(pos + 0.5);
    return fabs(pos - k) < GRID_SNAP ? k : pos;
}

/* Advance the run by h seconds, split at the grid points it crosses. */
static void advance(Lti *s, double h) {
    double end = snap(s->pos + h / s->h0);
    while (s->pos < end) {
        int64_t j = (int64_t)floor(s->pos);
        double stop = fmin(end, (double)(j + 1));
        advance_piece(s, j, s->pos, stop);
        s->pos = stop;
    }
}

/* dz/dt at the current time: lambda z + wb . f(t), the built-in forces interpolated between the grid
   samples around the time and the inputs, as (re, im) pairs into d (2 r doubles). */
static void derivatives_now(Lti *s, double *d) {
    double p = snap(s->pos);
    int64_t j = (int64_t)floor(p);
    const Forces *f0, *f1;
    grid_pair(s, j, &f0, &f1);
    double w = p - (double)j, f[4];
    for (int q = 0; q < 4; q++) f[q] = f0->f[q] + w * (f1->f[q] - f0->f[q]);
    memset(d, 0, (size_t)(2 * s->r) * 8);
    add_modal_force(s, f0->port, f, 4, d);
    if (s->n_in) add_modal_force(s, s->in_port, s->u, s->n_in, d);
    const double *lam = (const double *)s->lam, *z = (const double *)s->z;
    for (int i = 0; i < 2 * s->r; i += 2) {
        d[i] += lam[i] * z[i] - lam[i + 1] * z[i + 1];
        d[i + 1] += lam[i] * z[i + 1] + lam[i + 1] * z[i];
    }
}

static void update_outputs(Lti *s) {
    for (int c = 0; c < s->m; c++) {
        const cplx *row = s->cv + (size_t)c * s->r;
        const double *cv = (const double *)row, *z = (const double *)s->z; /* (re, im) pairs */
        double acc0 = 0.0, acc1 = 0.0;
        for (int i = 0; i < 2 * s->r; i += 2) {
            acc0 += cv[i] * z[i];
            acc1 += cv[i + 1] * z[i + 1];
        }
        s->y[c] = acc0 - acc1;
    }
    if (s->noise_std > 0 && s->m) {
        uint64_t j = (uint64_t)floor(s->pos + GRID_SNAP); /* constant between grid points */
        double *g = s->scratch;
        gauss_run(seed_of(s->noise_seed), j * (uint64_t)s->m, s->m, g);
        for (int c = 0; c < s->m; c++) s->y[c] += s->noise_std * g[c];
    }
}

/* The stationary state at the start time (see twin.fmu.steady): the unbalance's periodic state of the
   grid's first-order hold, the turbulence response drawn from its stationary law, and the first-order
   hold's share of the first turbulence force. */
static void steady_state(Lti *s) {
    const Coefs *c = coefs(s, s->h0);
    cplx q = cexp(I * s->omega * s->h0);
    /* force Re(U e^{i w t}) with U = (1, -i) me w^2 e^{i phase} at the unbalance node's x and y ports */
    cplx amp = s->unb_me * s->omega * s->omega * cexp(I * (s->unb_phase + s->omega * s->t0));
    Forces f;
    grid_forces(s, 0, &f);
    uint64_t seed = seed_of(s->turb_seed) ^ STEADY_STREAM;
    double *g = malloc((size_t)s->n * 8);
    int draw = g && s->turb_x >= 0 && s->turb_asd > 0;
    if (draw) gauss_run(seed, 0, s->n, g);
    for (int k = 0; draw && k < s->n; k++) g[k] *= s->turb_asd;
    for (int i = 0; i < s->r; i++) {
        cplx wx = s->wbt[(size_t)f.port[0] * s->r + i], wy = s->wbt[(size_t)f.port[1] * s->r + i];
        cplx alpha = (wx - I * wy) * amp, beta = (wx + I * wy) * conj(amp); /* wb.F = (alpha e^{iwt} + beta e^{-iwt})/2 */
        cplx gain_p = (c->g0[i] + c->g1[i] * (q - 1.0)) / (q - c->a[i]);
        cplx gain_m = (c->g0[i] + c->g1[i] * (conj(q) - 1.0)) / (conj(q) - c->a[i]);
        cplx zi = s->unb_me != 0.0 ? 0.5 * (alpha * gain_p + beta * gain_m) : 0.0;
        if (draw) {
            const cplx *row = s->steady_f + (size_t)i * s->n;
            for (int k = 0; k < s->n; k++) zi += row[k] * g[k];
            zi += c->g1[i] * modal_force(s, i, f.port + 2, f.f + 2, 2);
        }
        s->z[i] += zi;
    }
    free(g);
}

static void free_lti(Lti *s) {
    if (!s) return;
    free(s->in_port); free(s->lam); free(s->wbt); free(s->cv); free(s->steady_f);
    for (int k = 0; k < N_CACHE; k++) { free(s->cache[k].a); free(s->cache[k].g0); free(s->cache[k].g1); }
    free(s->z); free(s->y); free(s->u); free(s->scratch); free(s->zeros); free(s->der);
    free(s);
}
/* Read the resource file into s and its GUID (the instantiation token) into guid[64]: 1, or 0 with a message logged. */
static int load(Lti *s, FILE *f, char *guid) {
    char magic[8];
    int32_t dims[9];
    double hw[6];
    if (!read_block(f, magic, 1, 8) || memcmp(magic, MAGIC, 8) != 0) {
        logmsg(s, TWIN_ERROR, "resource file twin_lti.bin has another format than this runtime's (" MAGIC
                             "): the FMU mixes files of two twin versions; export it again");
        return 0;
    }
    int ok = read_block(f, dims, 4, 9) && read_block(f, hw, 8, 6) && read_block(f, guid, 1, 64);
    if (ok) {
        s->r = dims[0]; s->n = dims[1]; s->p = dims[2]; s->m = dims[3]; s->n_in = dims[4];
        s->turb_x = dims[5]; s->turb_y = dims[6];
        s->unb_node_start = dims[7]; /* start value of the unbalance_node parameter */
        s->has_steady = dims[8];
        s->h0 = hw[0]; s->omega = hw[1];
        for (int k = 0; k < 4; k++) s->start[k] = hw[2 + k];
        ok = s->r > 0 && s->n > 0 && s->p > 0 && s->m >= 0 && s->n_in >= 0 && s->h0 > 0;
    }
    if (ok) {
        size_t r = s->r, n = s->n, p = s->p, m = s->m, c = sizeof(cplx), n_in = s->n_in ? s->n_in : 1;
        s->in_port = calloc(n_in, sizeof(int));
        s->lam = malloc(r * c); s->wbt = malloc(p * r * c); s->cv = malloc((m ? m : 1) * r * c);
        s->steady_f = malloc((s->has_steady ? n : 1) * r * c); /* the steady start's factor, when exported */
        s->z = calloc(r, c); s->y = calloc(m ? m : 1, 8); s->u = calloc(n_in, 8);
        s->scratch = malloc((2 * r + m + 1) * 8);
        s->zeros = calloc(2 * r, 8);
        s->der = calloc(2 * r, 8);
        ok = s->in_port && s->lam && s->wbt && s->cv && s->steady_f && s->z && s->y && s->u && s->scratch && s->zeros &&
             s->der;
        for (int k = 0; ok && k < N_CACHE; k++) {
            s->cache[k].a = malloc(r * c); s->cache[k].g0 = malloc(r * c); s->cache[k].g1 = malloc(r * c);
            ok = s->cache[k].a && s->cache[k].g0 && s->cache[k].g1;
        }
        int32_t *tmp = calloc(n_in, 4);
        ok = ok && tmp && read_block(f, tmp, 4, s->n_in) && read_block(f, s->lam, c, r) &&
             read_block(f, s->wbt, c, p * r) && read_block(f, s->cv, c, m * r) &&
             (!s->has_steady || read_block(f, s->steady_f, c, r * n));
        for (int i = 0; ok && i < s->n_in; i++) {
            s->in_port[i] = tmp[i];
            if (tmp[i] < 0 || tmp[i] >= s->p) ok = 0;
        }
        free(tmp);
    }
    if (!ok) {
        logmsg(s, TWIN_ERROR, "resource file twin_lti.bin is corrupt or truncated");
        return 0;
    }
    guid[63] = 0;
    coefs(s, s->h0); /* slot 0: the grid step, kept */
    return 1;
}


/* A new instance: the resource file read and the token checked (NULL, with a message logged, if not). The
   resource location is a file URI (is_uri, FMI 2.0) or a folder path (FMI 3.0). */
static Lti *lti_new(const char *name, const char *token, const char *resources, int is_uri, int model_exchange,
                    int fmi_version, void *env, void (*logger)(void)) {
    Lti *s = calloc(1, sizeof(Lti));
    if (!s) return NULL;
    s->fmi_version = fmi_version;
    s->env = env;
    s->logger = logger;
    s->model_exchange = model_exchange;
    snprintf(s->name, sizeof s->name, "%s", name ? name : "twin");
    char path[4096], file[4200], fguid[64];
    if (is_uri) uri_to_path(resources ? resources : "", path, sizeof path);
    else snprintf(path, sizeof path, "%s", resources ? resources : "");
    size_t len = strlen(path);
    snprintf(file, sizeof file, "%s%stwin_lti.bin", path, (len && path[len - 1] == '/') ? "" : "/");
    FILE *f = fopen(file, "rb");
    if (!f) {
        char msg[4400];
        snprintf(msg, sizeof msg, "cannot open resource file %s", file);
        logmsg(s, TWIN_ERROR, msg);
        free_lti(s);
        return NULL;
    }
    int ok = load(s, f, fguid);
    fclose(f);
    if (ok && (!token || strcmp(token, fguid) != 0)) {
        logmsg(s, TWIN_ERROR, "the modelDescription's GUID (instantiation token) does not match the resource file");
        ok = 0;
    }
    if (!ok) {
        free_lti(s);
        return NULL;
    }
    to_start_values(s);
    return s;
}

static double lti_time(const Lti *s) { return s->t0 + s->pos * s->h0; }

static void lti_setup(Lti *s, double start) {
    s->t0 = start;
    s->pos = 0;
}

/* Leave initialisation: the state at the start time (at rest, or the steady start) and its outputs. */
static int lti_start(Lti *s, const char *fn) {
    if (s->unb_node < 0 || 2 * s->unb_node + 1 >= s->p)
        return fail(s, fn, "unbalance_node is not a node of the model:", s->unb_node);
    memset(s->z, 0, (size_t)s->r * sizeof(cplx));
    s->pos = 0;
    forget_samples(s);
    if (s->steady) steady_state(s);
    update_outputs(s);
    s->initialised = 1;
    return TWIN_OK;
}

static int lti_step(Lti *s, const char *fn, double h) {
    if (!s->initialised) return fail(s, fn, "called before the end of initialisation", -1);
    if (!(h >= 0) || !isfinite(h)) {
        char msg[256];
        snprintf(msg, sizeof msg, "%s: communication step %.17g s is not a non-negative number", fn, h);
        logmsg(s, TWIN_ERROR, msg);
        return TWIN_ERROR;
    }
    advance(s, h);
    update_outputs(s);
    return TWIN_OK;
}

/* ---- values by value reference --------------------------------------------------------- */
/* Bring the outputs and the derivatives up to the host's time and states (model exchange), once per get. */
static void lti_refresh(Lti *s) {
    if (s->model_exchange && s->initialised) {
        update_outputs(s);
        derivatives_now(s, s->der);
    }
}

static int get_real(Lti *s, const char *fn, unsigned r, double *v) {
    unsigned n2 = 2u * (unsigned)s->r;
    if (r >= VR_OUTPUT0 && r < VR_OUTPUT0 + (unsigned)s->m) *v = s->y[r - VR_OUTPUT0];
    else if (r == VR_TIME) *v = lti_time(s);
    else if (r >= VR_STATE0 && r < VR_STATE0 + n2) *v = ((const double *)s->z)[r - VR_STATE0];
    else if (r >= VR_DER0 && r < VR_DER0 + n2) {
        if (!s->model_exchange) derivatives_now(s, s->der);
        *v = s->der[r - VR_DER0];
    }
    else if (r >= VR_INPUT0 && r < VR_INPUT0 + (unsigned)s->n_in) *v = s->u[r - VR_INPUT0];
    else if (r == VR_UNBALANCE_ME) *v = s->unb_me;
    else if (r == VR_UNBALANCE_PHASE) *v = s->unb_phase;
    else if (r == VR_TURBULENCE_ASD) *v = s->turb_asd;
    else if (r == VR_NOISE_STD) *v = s->noise_std;
    else return fail(s, fn, "no real variable has value reference", (long)r);
    return TWIN_OK;
}

static int set_real(Lti *s, const char *fn, unsigned r, double v) {
    if (r >= VR_INPUT0 && r < VR_INPUT0 + (unsigned)s->n_in) s->u[r - VR_INPUT0] = v;
    else if (r != VR_UNBALANCE_ME && r != VR_UNBALANCE_PHASE && r != VR_TURBULENCE_ASD && r != VR_NOISE_STD)
        return fail(s, fn, "no real input or parameter has value reference", (long)r);
    else if (s->initialised) /* fixed parameters */
        return fail(s, fn, "parameters are fixed after initialisation; value reference", (long)r);
    else if (r == VR_UNBALANCE_ME) s->unb_me = v;
    else if (r == VR_UNBALANCE_PHASE) s->unb_phase = v;
    else if (r == VR_TURBULENCE_ASD) s->turb_asd = v;
    else s->noise_std = v;
    return TWIN_OK;
}

static int get_int(Lti *s, const char *fn, unsigned r, long *v) {
    if (r == VR_UNBALANCE_NODE) *v = s->unb_node;
    else if (r == VR_TURBULENCE_SEED) *v = s->turb_seed;
    else if (r == VR_NOISE_SEED) *v = s->noise_seed;
    else return fail(s, fn, "no integer variable has value reference", (long)r);
    return TWIN_OK;
}

static int set_int(Lti *s, const char *fn, unsigned r, long v) {
    if (r != VR_UNBALANCE_NODE && r != VR_TURBULENCE_SEED && r != VR_NOISE_SEED)
        return fail(s, fn, "no integer parameter has value reference", (long)r);
    if (s->initialised) return fail(s, fn, "parameters are fixed after initialisation; value reference", (long)r);
    if (v < INT32_MIN || v > INT32_MAX) return fail(s, fn, "the value does not fit a 32-bit integer; value reference", (long)r);
    if (r == VR_UNBALANCE_NODE) s->unb_node = (int)v;
    else if (r == VR_TURBULENCE_SEED) s->turb_seed = (int)v;
    else s->noise_seed = (int)v;
    return TWIN_OK;
}

static int get_bool(Lti *s, const char *fn, unsigned r, int *v) {
    if (r != VR_STEADY_START) return fail(s, fn, "no Boolean variable has value reference", (long)r);
    *v = s->steady;
    return TWIN_OK;
}

static int set_bool(Lti *s, const char *fn, unsigned r, int v) {
    if (r != VR_STEADY_START) return fail(s, fn, "no Boolean parameter has value reference", (long)r);
    if (s->initialised) return fail(s, fn, "parameters are fixed after initialisation; value reference", (long)r);
    if (v && !s->has_steady) return fail(s, fn, "steady_start: this FMU was exported without a steady start", -1);
    s->steady = v ? 1 : 0;
    return TWIN_OK;
}

/* ---- FMU state ----------------------------------------------------------------------- */
typedef struct {
    double t0, pos, unb_me, unb_phase, turb_asd, noise_std;
    int unb_node, turb_seed, noise_seed, initialised, steady;
    cplx *z;
    double *y, *u;
} Snapshot;

static void free_snapshot(Snapshot *q) {
    if (!q) return;
    free(q->z); free(q->y); free(q->u);
    free(q);
}

/* The run state's fields, of the same name and type in Lti and Snapshot: one list for both directions. */
#define RUN_STATE(X) X(t0) X(pos) X(unb_me) X(unb_phase) X(turb_asd) X(noise_std) \
    X(unb_node) X(turb_seed) X(noise_seed) X(initialised) X(steady)
#define COPY_FIELD(f)                                                                        \
    {                                                                                        \
        _Static_assert(sizeof dst->f == sizeof src->f, "run-state field " #f " differs in size"); \
        memcpy(&dst->f, &src->f, sizeof dst->f);                                             \
    }

/* Copy the modal state, outputs and inputs (sizes of the system s). */
static void copy_vectors(const Lti *s, cplx *z, double *y, double *u, const cplx *fz, const double *fy,
                         const double *fu) {
    memcpy(z, fz, (size_t)s->r * sizeof(cplx));
    memcpy(y, fy, (size_t)(s->m ? s->m : 1) * 8);
    memcpy(u, fu, (size_t)(s->n_in ? s->n_in : 1) * 8);
}

static void take(const Lti *src, Snapshot *dst) {
    RUN_STATE(COPY_FIELD)
    copy_vectors(src, dst->z, dst->y, dst->u, src->z, src->y, src->u);
}

static void give(Lti *dst, const Snapshot *src) {
    forget_samples(dst);
    RUN_STATE(COPY_FIELD)
    copy_vectors(dst, dst->z, dst->y, dst->u, src->z, src->y, src->u);
}

static Snapshot *new_snapshot(const Lti *s) {
    Snapshot *q = calloc(1, sizeof(Snapshot));
    if (!q) return NULL;
    q->z = malloc((size_t)s->r * sizeof(cplx));
    q->y = malloc((size_t)(s->m ? s->m : 1) * 8);
    q->u = malloc((size_t)(s->n_in ? s->n_in : 1) * 8);
    if (!q->z || !q->y || !q->u) {
        free_snapshot(q);
        return NULL;
    }
    return q;
}


static void *lti_get_state(Lti *s, const char *fn, void *previous) {
    Snapshot *q = (Snapshot *)previous;
    if (!q) q = new_snapshot(s);
    if (!q) {
        fail(s, fn, "out of memory", -1);
        return NULL;
    }
    take(s, q);
    return q;
}

/* Bytes: magic, int32 r, m, n_in, unb_node, seeds (2), initialised, steady, doubles t0, pos, parameters (4),
   z (2 r), y, u. */
#define STATE_INTS 8
#define STATE_DOUBLES 6
static size_t state_bytes(const Lti *s) {
    return 8 + 4 * STATE_INTS + 8 * (STATE_DOUBLES + 2 * (size_t)s->r + (size_t)s->m + (size_t)s->n_in);
}

static void put(unsigned char **p, const void *v, size_t size) { memcpy(*p, v, size); *p += size; }
static void get(const unsigned char **p, void *v, size_t size) { memcpy(v, *p, size); *p += size; }


static int lti_serialize(Lti *s, const char *fn, const Snapshot *q, unsigned char *b, size_t n) {
    if (!q) return fail(s, fn, "no state given (NULL)", -1);
    if (n < state_bytes(s)) return fail(s, fn, "buffer too small; bytes needed:", (long)state_bytes(s));
    unsigned char *p = b;
    int32_t ints[STATE_INTS] = {s->r, s->m, s->n_in, q->unb_node, q->turb_seed, q->noise_seed, q->initialised,
                                q->steady};
    double d[STATE_DOUBLES] = {q->t0, q->pos, q->unb_me, q->unb_phase, q->turb_asd, q->noise_std};
    put(&p, STATE_MAGIC, 8);
    put(&p, ints, sizeof ints);
    put(&p, d, sizeof d);
    put(&p, q->z, (size_t)s->r * sizeof(cplx));
    put(&p, q->y, (size_t)s->m * 8);
    put(&p, q->u, (size_t)s->n_in * 8);
    return TWIN_OK;
}

static Snapshot *lti_deserialize(Lti *s, const char *fn, const unsigned char *b, size_t n) {
    if (n != state_bytes(s) || memcmp(b, STATE_MAGIC, 8) != 0) {
        fail(s, fn, "not a state of this FMU; bytes given:", (long)n);
        return NULL;
    }
    const unsigned char *p = b + 8;
    int32_t ints[STATE_INTS];
    double d[STATE_DOUBLES];
    get(&p, ints, sizeof ints);
    if (ints[0] != s->r || ints[1] != s->m || ints[2] != s->n_in) {
        fail(s, fn, "a state of another system; its number of modes:", (long)ints[0]);
        return NULL;
    }
    Snapshot *q = new_snapshot(s);
    if (!q) {
        fail(s, fn, "out of memory", -1);
        return NULL;
    }
    q->unb_node = ints[3]; q->turb_seed = ints[4]; q->noise_seed = ints[5]; q->initialised = ints[6];
    q->steady = ints[7];
    get(&p, d, sizeof d);
    q->t0 = d[0]; q->pos = d[1]; q->unb_me = d[2]; q->unb_phase = d[3]; q->turb_asd = d[4]; q->noise_std = d[5];
    get(&p, q->z, (size_t)s->r * sizeof(cplx));
    get(&p, q->y, (size_t)s->m * 8);
    get(&p, q->u, (size_t)s->n_in * 8);
    return q;
}

/* The Jacobian of the linear system times a seed: unknowns are state derivatives or outputs, knowns are
   continuous states or inputs (d der(z)/dz = the 2 x 2 block of lambda, d der(z)/du = wb, dy/dz = cv,
   dy/du = 0). */
static int lti_directional(Lti *s, const char *fn, const unsigned unknown[], size_t n_unknown,
                           const unsigned known[], size_t n_known, const double seed[], double out[]) {
    unsigned n2 = 2u * (unsigned)s->r;
    double *dz = calloc(n2 + (size_t)s->n_in + 1, 8), *du = dz ? dz + n2 : NULL;
    if (!dz) return fail(s, fn, "out of memory", -1);
    int st = TWIN_OK;
    for (size_t k = 0; k < n_known && st == TWIN_OK; k++) {
        unsigned r = known[k];
        if (r >= VR_STATE0 && r < VR_STATE0 + n2) dz[r - VR_STATE0] += seed[k];
        else if (r >= VR_INPUT0 && r < VR_INPUT0 + (unsigned)s->n_in) du[r - VR_INPUT0] += seed[k];
        else st = fail(s, fn, "a known must be a state or an input; value reference", (long)r);
    }
    const double *lam = (const double *)s->lam, *z = dz;
    for (size_t k = 0; k < n_unknown && st == TWIN_OK; k++) {
        unsigned r = unknown[k];
        if (r >= VR_DER0 && r < VR_DER0 + n2) {
            unsigned e = r - VR_DER0, i = e & ~1u; /* the mode's real part */
            double v = e % 2 ? lam[i] * z[i + 1] + lam[i + 1] * z[i] : lam[i] * z[i] - lam[i + 1] * z[i + 1];
            for (int q = 0; q < s->n_in; q++) v += ((const double *)(s->wbt + (size_t)s->in_port[q] * s->r))[e] * du[q];
            out[k] = v;
        } else if (r >= VR_OUTPUT0 && r < VR_OUTPUT0 + (unsigned)s->m) {
            const double *cv = (const double *)(s->cv + (size_t)(r - VR_OUTPUT0) * s->r);
            double v = 0.0;
            for (unsigned i = 0; i < n2; i += 2) v += cv[i] * z[i] - cv[i + 1] * z[i + 1];
            out[k] = v;
        } else {
            st = fail(s, fn, "an unknown must be a state derivative or an output; value reference", (long)r);
        }
    }
    free(dz);
    return st;
}

/* A state's nominal value, for the host's error control: the size of the mode's response to the built-in
   excitation, the larger of its stationary RMS under the turbulence (sqrt(|b|^2 asd^2 / (4 |Re lambda|)) for
   a white force of one-sided density asd, |b| the mode's input row at the turbulence node) and its amplitude
   under the rotating unbalance (its forward and backward parts, as in steady_state); the static response
   to 1 N without excitation. */
static void lti_nominals(const Lti *s, double x[]) {
    for (int i = 0; i < s->r; i++) {
        double bt = 0.0, v = 0.0;
        for (int q = 0; q < 2 && s->turb_x >= 0; q++)
            bt += pow(cabs(s->wbt[(size_t)(q ? s->turb_y : s->turb_x) * s->r + i]), 2);
        if (s->turb_asd > 0 && creal(s->lam[i]) < 0) v = sqrt(bt / (-4.0 * creal(s->lam[i]))) * s->turb_asd;
        if (s->unb_me > 0) {
            cplx wx = s->wbt[(size_t)(2 * s->unb_node) * s->r + i], wy = s->wbt[(size_t)(2 * s->unb_node + 1) * s->r + i];
            double a = 0.5 * s->unb_me * s->omega * s->omega;
            v = fmax(v, a * (cabs(wx - I * wy) / cabs(I * s->omega - s->lam[i]) +
                             cabs(wx + I * wy) / cabs(-I * s->omega - s->lam[i])));
        }
        if (!(v > 0)) {
            double w = 0.0;
            for (int q = 0; q < s->p; q++) w = fmax(w, cabs(s->wbt[(size_t)q * s->r + i]));
            v = w / cabs(s->lam[i]);
        }
        x[2 * i] = x[2 * i + 1] = v > 0 ? v : 1.0;
    }
}

/* ---- model exchange ---------------------------------------------------------------------- */
/* The only events are the grid points, where the built-in forces change slope and the sensor noise takes
   its next sample: time events, one grid step apart. */
static double lti_next_event(const Lti *s) { return s->t0 + (floor(s->pos + GRID_SNAP) + 1.0) * s->h0; }

static void lti_set_time(Lti *s, double t) { s->pos = (t - s->t0) / s->h0; }

static int lti_check_states(Lti *s, const char *fn, size_t nx) {
    return nx == 2 * (size_t)s->r ? TWIN_OK : fail(s, fn, "the FMU has 2 x its modes states, not", (long)nx);
}
