/* Levenberg-Marquardt for the hand-eye calibration on the local rotation chart, in C.
 *
 * The model is not written here: every derivative comes from the CasADi function
 * `normal_one` generated (model/compiled/fast.py) from the one symbolic source (model/chain/symbolic.py).
 * For one measurement i it returns H_i = J_i^T J_i (6 x 6), g_i = J_i^T e_i (6) and
 * f_i = |e_i|^2 / 2, with e_i = R1_i (R2 exp([d]x) xs_i + t2 + dt) + t1_i - c at d = 0, dt = 0.
 * This file sums them over the measurements and runs the iteration of model/compiled/fast.py's
 * Python fallback line for line (Marquardt's scaled damping, Nocedal & Wright 10.3):
 *
 *   solve (H + mu diag H) p = -g;   trial  t2 + p[0:3],  R2 exp([p[3:6]]x);
 *   accept if the cost falls (mu /= 3), else mu *= 4; when the predicted decrease is below
 *   the cost's rounding (100 eps max(1, f)) the cost cannot judge the step: accept it if
 *   max|g| falls, else stop (no measurable progress);
 *   stop when max|g| <= 1e-10 max(1, f) or the step is below 1e-12 (relative in mm, rad).
 * Large-residual data (thesis-real: RMS 5.6 mm) make Gauss-Newton converge linearly, so
 * stopping on the cost alone would end some 1e-6 mm short of the minimum.
 *
 * Compiled together with the generated source by model/compiled/fast.py (gcc -O3); called via ctypes.
 */
#include <math.h>
#include <string.h>

typedef long long int he_int; /* casadi_int of the generated code; checked at load time */
int normal_one(const double **arg, double **res, he_int *iw, double *w, int mem);

#ifndef HE_SZ_W
#define HE_SZ_W 64
#endif

/* The status codes of handeye.solvers.STATUS_MESSAGES, so that a code means one thing everywhere. */
enum { HE_MAXITER = 0, HE_GTOL = 1, HE_STALL = 2, HE_XTOL = 3, HE_NONFINITE = -1, HE_SINGULAR = -2, HE_DEGENERATE = -3 };

/* The 15 data of measurement i as the generated function takes them: R1 row-major, t1, xs,
 * read from the flange transform (4 x 4 row-major) and the measured centre. */
static void measurement(const double *f2b, const double *xs, double *d) {
    for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) d[3 * r + k] = f2b[4 * r + k];
        d[9 + r] = f2b[4 * r + 3];
        d[12 + r] = xs[r];
    }
}

static void evaluate(int n, const double *f2b, const double *xs, const double *c, const double *x, double *h,
                     double *g, double *f) {
    double w[HE_SZ_W], hi[36], gi[6], fi, d[15];
    const double *arg[4] = {x, x + 3, c, d};
    double *res[3] = {hi, gi, &fi};
    memset(h, 0, 36 * sizeof(double));
    memset(g, 0, 6 * sizeof(double));
    *f = 0.0;
    for (int i = 0; i < n; ++i) {
        measurement(f2b + 16 * i, xs + 3 * i, d);
        normal_one(arg, res, 0, w, 0);
        for (int k = 0; k < 36; ++k) h[k] += hi[k];
        for (int k = 0; k < 6; ++k) g[k] += gi[k];
        *f += fi;
    }
}

/* Solve A p = b for a symmetric positive definite 6 x 6 A (Cholesky); 0 if A is not. */
static int cholesky_solve(const double *a_in, const double *b, double *p) {
    double a[36], y[6];
    memcpy(a, a_in, sizeof a);
    for (int j = 0; j < 6; ++j) {
        double s = a[6 * j + j];
        for (int k = 0; k < j; ++k) s -= a[6 * j + k] * a[6 * j + k];
        if (!(s > 0.0)) return 0;
        a[6 * j + j] = sqrt(s);
        for (int i = j + 1; i < 6; ++i) {
            double t = a[6 * i + j];
            for (int k = 0; k < j; ++k) t -= a[6 * i + k] * a[6 * j + k];
            a[6 * i + j] = t / a[6 * j + j];
        }
    }
    for (int i = 0; i < 6; ++i) {
        double t = b[i];
        for (int k = 0; k < i; ++k) t -= a[6 * i + k] * y[k];
        y[i] = t / a[6 * i + i];
    }
    for (int i = 5; i >= 0; --i) {
        double t = y[i];
        for (int k = i + 1; k < 6; ++k) t -= a[6 * k + i] * p[k];
        p[i] = t / a[6 * i + i];
    }
    return 1;
}

/* 1 if the column-scaled J^T J has a Cholesky pivot^2 below 1e-12: some combination of the
 * six unknowns is not constrained by the data (too few or degenerate poses). */
static int rank_deficient(const double *h) {
    double s[36], d[6], b[6] = {0}, p[6];
    for (int i = 0; i < 6; ++i) {
        if (!(h[7 * i] > 0.0)) return 1;
        d[i] = 1.0 / sqrt(h[7 * i]);
    }
    for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) s[6 * i + j] = h[6 * i + j] * d[i] * d[j];
    for (int i = 0; i < 6; ++i) s[7 * i] -= 1e-12; /* PD only if every pivot^2 exceeds ~1e-12 */
    return !cholesky_solve(s, b, p);
}

/* out = r exp([w]x) (Rodrigues), 3 x 3 row-major. */
static void rotate(const double *r, const double *w, double *out) {
    double th2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2], th = sqrt(th2), a, b;
    if (th < 1e-8) {
        a = 1.0 - th2 / 6.0;
        b = 0.5 - th2 / 24.0;
    } else {
        a = sin(th) / th;
        b = (1.0 - cos(th)) / th2;
    }
    double k[9] = {0.0, -w[2], w[1], w[2], 0.0, -w[0], -w[1], w[0], 0.0}, e[9];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            double kk = 0.0;
            for (int l = 0; l < 3; ++l) kk += k[3 * i + l] * k[3 * l + j];
            e[3 * i + j] = (i == j) + a * k[3 * i + j] + b * kk;
        }
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            double s = 0.0;
            for (int l = 0; l < 3; ++l) s += r[3 * i + l] * e[3 * l + j];
            out[3 * i + j] = s;
        }
}

/* One calibration. f2b: n flange transforms (4 x 4 row-major, mm), xs: n measured centres (3),
 * c: sphere centre (3), s2f: sensor2flange (4 x 4 row-major), start in, result out.
 * info out: iterations, evaluations, cost, status, max|g|. Returns the status. */
int he_lm(int n, const double *f2b, const double *xs, const double *c, double *s2f, int max_iter, double *info) {
    const double eps = 2.220446049250313e-16;
    double x[12], h[36], g[6], f, hn[36], gn[6], fn, a[36], p[6], mg[6], xn[12], mu = 1e-6;
    int k = 0, evals = 1, status = HE_MAXITER;
    for (int r = 0; r < 3; ++r) { /* state: t2, R2 row-major */
        x[r] = s2f[4 * r + 3];
        for (int q = 0; q < 3; ++q) x[3 + 3 * r + q] = s2f[4 * r + q];
    }
    evaluate(n, f2b, xs, c, x, h, g, &f);
    for (;;) {
        double gmax = 0.0;
        for (int i = 0; i < 6; ++i) gmax = fmax(gmax, fabs(g[i]));
        if (!isfinite(f) || !isfinite(gmax)) { status = HE_NONFINITE; break; }
        if (gmax <= 1e-10 * fmax(1.0, f)) { status = HE_GTOL; break; }
        if (k >= max_iter) break;
        memcpy(a, h, sizeof a);
        for (int i = 0; i < 6; ++i) a[7 * i] += mu * h[7 * i];
        for (int i = 0; i < 6; ++i) mg[i] = -g[i];
        ++k;
        if (!cholesky_solve(a, mg, p)) {
            if (mu > 1e12) { status = HE_SINGULAR; break; }
            mu = fmax(mu * 4.0, 1e-12);
            continue;
        }
        double tnorm = 0.0, pt = 0.0, pr = 0.0, predicted = 0.0;
        for (int i = 0; i < 3; ++i) {
            tnorm = fmax(tnorm, fabs(x[i]));
            pt = fmax(pt, fabs(p[i]));
            pr = fmax(pr, fabs(p[3 + i]));
        }
        if (pt <= 1e-12 * (1.0 + tnorm) && pr <= 1e-12) { status = HE_XTOL; break; }
        for (int i = 0; i < 6; ++i) {
            double hp = 0.0;
            for (int j = 0; j < 6; ++j) hp += h[6 * i + j] * p[j];
            predicted -= g[i] * p[i] + 0.5 * p[i] * hp;
        }
        for (int i = 0; i < 3; ++i) xn[i] = x[i] + p[i];
        rotate(x + 3, p + 3, xn + 3);
        evaluate(n, f2b, xs, c, xn, hn, gn, &fn);
        ++evals;
        int accept;
        if (predicted <= 100.0 * eps * fmax(1.0, f)) {
            /* the decrease is below the cost's rounding: judge the step by the gradient */
            double gnmax = 0.0;
            for (int i = 0; i < 6; ++i) gnmax = fmax(gnmax, fabs(gn[i]));
            accept = gnmax < gmax;
            if (!accept) { status = HE_STALL; break; }
        } else {
            accept = fn < f;
        }
        if (accept) {
            memcpy(x, xn, sizeof xn);
            memcpy(h, hn, sizeof h);
            memcpy(g, gn, sizeof g);
            f = fn;
            mu = fmax(mu / 3.0, 1e-12);
        } else {
            mu *= 4.0;
        }
    }
    if (status > 0 && rank_deficient(h)) status = HE_DEGENERATE;
    for (int r = 0; r < 3; ++r) {
        s2f[4 * r + 3] = x[r];
        for (int q = 0; q < 3; ++q) s2f[4 * r + q] = x[3 + 3 * r + q];
    }
    s2f[12] = s2f[13] = s2f[14] = 0.0;
    s2f[15] = 1.0;
    double gmax = 0.0;
    for (int i = 0; i < 6; ++i) gmax = fmax(gmax, fabs(g[i]));
    info[0] = k;
    info[1] = evals;
    info[2] = f;
    info[3] = status;
    info[4] = gmax;
    return status;
}

/* m independent calibrations of n measurements each: f2b m x n x 16, xs m x n x 3, c m x 3,
 * s2f m x 16, info m x 5. For Monte Carlo studies: one call, no Python in between.
 * Returns the number that did not converge. */
int he_lm_batch(int m, int n, const double *f2b, const double *xs, const double *c, double *s2f, int max_iter,
                double *info) {
    int failed = 0;
    for (int j = 0; j < m; ++j)
        failed += he_lm(n, f2b + (long)16 * n * j, xs + (long)3 * n * j, c + 3 * j, s2f + 16 * j, max_iter,
                        info + 5 * j) <= HE_MAXITER;
    return failed;
}
