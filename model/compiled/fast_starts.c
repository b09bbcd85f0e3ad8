/* The batchable solvers of handeye.solvers, one start at a time, in C: the compiled per-start loop.
 *
 * No function or derivative is written here: he_f (f), he_g (grad f), he_h (Hessian of f,
 * row-major), he_r (residual) and he_j (its Jacobian, row-major) are CasADi functions generated
 * (model/compiled/fast_starts.py) from the one symbolic source (model/chain/symbolic.py, via model/chain/codegen.py).
 * This file is the iteration of each method of solvers/ (newton.py, line_search.py,
 * gauss_newton.py, levenberg_marquardt.py, trust_region.py) for one row of the batch, rule for
 * rule, with the same stopping tests and counters; comments name the Python it follows. Points
 * move by x + p (no retraction). Sums run left to right as solvers/stacks.py adds them, and the
 * build turns fused multiply-adds off, so a row rounds as numpy rounds it, up to the small linear
 * algebra: LU with partial pivoting (LAPACK's gesv), Jacobi's symmetric eigensolver (eigh) and
 * one-sided Jacobi SVD (lstsq) give the same answers to round-off, not bit for bit.
 *
 * Compiled with -DHE_N (unknowns), -DHE_M (residuals), -DHE_SZ_W, -DHE_SZ_IW (work of the
 * generated functions).
 */
#include <math.h>
#include <string.h>

typedef long long int he_int; /* casadi_int of the generated code */
int he_f(const double **arg, double **res, he_int *iw, double *w, int mem);
int he_g(const double **arg, double **res, he_int *iw, double *w, int mem);
int he_h(const double **arg, double **res, he_int *iw, double *w, int mem);
int he_r(const double **arg, double **res, he_int *iw, double *w, int mem);
int he_j(const double **arg, double **res, he_int *iw, double *w, int mem);

#define N HE_N
#define M HE_M
#define EPS 2.220446049250313e-16
#define C1 1e-4
#define C2 0.9
#define RHO_LS 0.5

/* methods, in the order of fast_starts.METHODS */
enum { NEWTON, NEWTON_LS, SD, BFGS, GN, LM, TR };
/* messages beyond the status table (line_search.AT_PRECISION, NO_STEP) */
enum { MSG_NONE, MSG_AT_PRECISION, MSG_NO_STEP };

typedef struct {
    int max_iter;
    double gtol, ftol, xtol, eta, lm_tau, max_radius_factor, initial_radius;
    int scaling;
} opts_t;

typedef struct {
    double x[N], f, g[N];
    int it, nfev, njev, nhev, status, msg, rankdef, done;
} row_t;

/* -- the generated functions ------------------------------------------------------------------ */
typedef int (*gen_t)(const double **, double **, he_int *, double *, int);

static void call(gen_t fn, const double *x, double *out) {
    double w[HE_SZ_W];
    he_int iw[HE_SZ_IW];
    const double *arg[1] = {x};
    double *res[1] = {out};
    fn(arg, res, iw, w, 0);
}

static double cost(row_t *s, const double *x) { double v; s->nfev++; call(he_f, x, &v); return v; }
static void grad(row_t *s, const double *x, double *g) { s->njev++; call(he_g, x, g); }
static void hess(row_t *s, const double *x, double *h) { s->nhev++; call(he_h, x, h); }
static void resid(row_t *s, const double *x, double *r) { s->nfev++; call(he_r, x, r); }
static void jac(row_t *s, const double *x, double *j) { s->njev++; call(he_j, x, j); }

/* -- solvers/stacks.py and solvers/result.py, one row ----------------------------------------- */
static double nmax(double a, double b) { return isnan(a) ? a : isnan(b) ? b : (a >= b ? a : b); } /* np.maximum */
static double nmin(double a, double b) { return isnan(a) ? a : isnan(b) ? b : (a <= b ? a : b); } /* np.minimum */

static double dot(const double *a, const double *b, int n) {
    double t = a[0] * b[0];
    for (int i = 1; i < n; ++i) t += a[i] * b[i];
    return t;
}
static double norm(const double *a, int n) { return sqrt(dot(a, a, n)); }
static double dot_ones(const double *a) { /* stacks.row_sum */
    double t = a[0];
    for (int i = 1; i < N; ++i) t += a[i];
    return t;
}
static double max_abs(const double *a, int n) {
    double t = fabs(a[0]);
    for (int i = 1; i < n; ++i) t = nmax(t, fabs(a[i]));
    return t;
}
static int all_finite(const double *a, int n) {
    for (int i = 0; i < n; ++i)
        if (!isfinite(a[i])) return 0;
    return 1;
}
/* out = a v, a (r x c) row-major, summed over columns left to right (stacks.matvec) */
static void matvec(const double *a, const double *v, int r, int c, double *out) {
    for (int i = 0; i < r; ++i) {
        double t = a[c * i] * v[0];
        for (int j = 1; j < c; ++j) t += a[c * i + j] * v[j];
        out[i] = t;
    }
}
/* out = a^T v, a (r x c) row-major (stacks.transpose_times) */
static void tmatvec(const double *a, const double *v, int r, int c, double *out) {
    for (int j = 0; j < c; ++j) {
        double t = a[j] * v[0];
        for (int i = 1; i < r; ++i) t += a[c * i + j] * v[i];
        out[j] = t;
    }
}
/* p^T b p as stacks.quad_rows: (b^T p) . p */
static double quad(const double *p, const double *b) {
    double t[N];
    tmatvec(b, p, N, N, t);
    return dot(t, p, N);
}
static void gram(const double *j, double *a) { /* J^T J, (M x N) -> (N x N) */
    for (int r = 0; r < N; ++r)
        for (int c = 0; c < N; ++c) {
            double t = j[r] * j[c];
            for (int i = 1; i < M; ++i) t += j[N * i + r] * j[N * i + c];
            a[N * r + c] = t;
        }
}
static int gradient_small(const double *g, double f, const opts_t *o) {
    return max_abs(g, N) <= o->gtol * nmax(1.0, fabs(f));
}
static int step_small(const double *p, const double *x, const opts_t *o) {
    return norm(p, N) <= o->xtol * (o->xtol + norm(x, N));
}
static int reduction_small(double f_old, double f_new, const opts_t *o) {
    return fabs(f_old - f_new) <= o->ftol * nmax(1.0, fabs(f_old));
}
static void stop(row_t *s, int status, int it) { s->status = status; s->it = it; s->done = 1; }

/* Solve a p = b (LU, partial pivoting as LAPACK's getrf); 0 where a pivot is exactly zero. */
static int solve(const double *a_in, const double *b, double *p) {
    double a[N * N];
    memcpy(a, a_in, sizeof a);
    memcpy(p, b, N * sizeof(double));
    for (int k = 0; k < N; ++k) {
        int piv = k;
        for (int i = k + 1; i < N; ++i)
            if (fabs(a[N * i + k]) > fabs(a[N * piv + k])) piv = i;
        if (a[N * piv + k] == 0.0) {
            for (int i = 0; i < N; ++i) p[i] = NAN;
            return 0;
        }
        if (piv != k) {
            for (int c = 0; c < N; ++c) { double t = a[N * k + c]; a[N * k + c] = a[N * piv + c]; a[N * piv + c] = t; }
            double t = p[k]; p[k] = p[piv]; p[piv] = t;
        }
        for (int i = k + 1; i < N; ++i) {
            double l = a[N * i + k] / a[N * k + k];
            for (int c = k + 1; c < N; ++c) a[N * i + c] -= l * a[N * k + c];
            p[i] -= l * p[k];
        }
    }
    for (int k = N - 1; k >= 0; --k) {
        for (int c = k + 1; c < N; ++c) p[k] -= a[N * k + c] * p[c];
        p[k] /= a[N * k + k];
    }
    return 1;
}

/* Symmetric eigenproblem a = v diag(w) v^T by cyclic Jacobi rotations (as numpy.linalg.eigh:
 * w ascending, eigenvectors in the columns of v, row-major). */
static void eigh(const double *a_in, double *w, double *v) {
    double a[N * N];
    memcpy(a, a_in, sizeof a);
    for (int i = 0; i < N * N; ++i) v[i] = (i % (N + 1) == 0) ? 1.0 : 0.0;
    for (int sweep = 0; sweep < 60; ++sweep) {
        double off = 0.0;
        for (int p = 0; p < N; ++p)
            for (int q = p + 1; q < N; ++q) off += fabs(a[N * p + q]);
        if (off == 0.0) break;
        for (int p = 0; p < N; ++p)
            for (int q = p + 1; q < N; ++q) {
                double apq = a[N * p + q];
                if (apq == 0.0) continue;
                double theta = (a[N * q + q] - a[N * p + p]) / (2.0 * apq);
                double t = fabs(theta) > 1e150 ? 0.5 / theta
                                                : (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                double c = 1.0 / sqrt(t * t + 1.0), sn = t * c;
                for (int k = 0; k < N; ++k) { /* a <- a G (columns p, q) */
                    double akp = a[N * k + p], akq = a[N * k + q];
                    a[N * k + p] = c * akp - sn * akq;
                    a[N * k + q] = sn * akp + c * akq;
                }
                for (int k = 0; k < N; ++k) { /* a <- G^T a (rows p, q) */
                    double apk = a[N * p + k], aqk = a[N * q + k];
                    a[N * p + k] = c * apk - sn * aqk;
                    a[N * q + k] = sn * apk + c * aqk;
                }
                a[N * p + q] = a[N * q + p] = 0.0;
                for (int k = 0; k < N; ++k) {
                    double vkp = v[N * k + p], vkq = v[N * k + q];
                    v[N * k + p] = c * vkp - sn * vkq;
                    v[N * k + q] = sn * vkp + c * vkq;
                }
            }
    }
    for (int i = 0; i < N; ++i) w[i] = a[N * i + i];
    for (int i = 1; i < N; ++i) /* insertion sort, ascending, columns of v along */
        for (int j = i; j > 0 && w[j] < w[j - 1]; --j) {
            double t = w[j]; w[j] = w[j - 1]; w[j - 1] = t;
            for (int k = 0; k < N; ++k) { t = v[N * k + j]; v[N * k + j] = v[N * k + j - 1]; v[N * k + j - 1] = t; }
        }
}

/* Minimum-norm least-squares solution of j p = b (j: M x N) and the rank of j, as
 * stacks.lstsq_rows: singular values below eps max(M, N) s_max count as zero. The SVD by
 * one-sided Jacobi rotations of j's columns (Hestenes). */
static int lstsq(const double *j, const double *b, double *p) {
    double a[M * N], v[N * N], s[N], coef[N];
    memcpy(a, j, sizeof a);
    for (int i = 0; i < N * N; ++i) v[i] = (i % (N + 1) == 0) ? 1.0 : 0.0;
    for (int sweep = 0; sweep < 60; ++sweep) {
        int rotated = 0;
        for (int c = 0; c < N; ++c)
            for (int d = c + 1; d < N; ++d) {
                double alpha = 0.0, beta = 0.0, gamma = 0.0;
                for (int i = 0; i < M; ++i) {
                    alpha += a[N * i + c] * a[N * i + c];
                    beta += a[N * i + d] * a[N * i + d];
                    gamma += a[N * i + c] * a[N * i + d];
                }
                if (!(fabs(gamma) > EPS * sqrt(alpha * beta))) continue;
                rotated = 1;
                double zeta = (beta - alpha) / (2.0 * gamma);
                double t = fabs(zeta) > 1e150 ? 0.5 / zeta
                                               : (zeta >= 0 ? 1.0 : -1.0) / (fabs(zeta) + sqrt(1.0 + zeta * zeta));
                double cs = 1.0 / sqrt(1.0 + t * t), sn = cs * t;
                for (int i = 0; i < M; ++i) {
                    double ac = a[N * i + c], ad = a[N * i + d];
                    a[N * i + c] = cs * ac - sn * ad;
                    a[N * i + d] = sn * ac + cs * ad;
                }
                for (int i = 0; i < N; ++i) {
                    double vc = v[N * i + c], vd = v[N * i + d];
                    v[N * i + c] = cs * vc - sn * vd;
                    v[N * i + d] = sn * vc + cs * vd;
                }
            }
        if (!rotated) break;
    }
    double smax = 0.0;
    for (int c = 0; c < N; ++c) {
        double t = 0.0;
        for (int i = 0; i < M; ++i) t += a[N * i + c] * a[N * i + c];
        s[c] = sqrt(t);
        smax = nmax(smax, s[c]);
    }
    int rank = 0;
    for (int c = 0; c < N; ++c) {
        int keep = s[c] > EPS * (M > N ? M : N) * smax;
        double ub = 0.0; /* u_c . b with u_c = a_c / s_c */
        for (int i = 0; i < M; ++i) ub += (keep ? a[N * i + c] / s[c] : 0.0) * b[i];
        coef[c] = keep ? ub / s[c] : 0.0;
        rank += keep;
    }
    matvec(v, coef, N, N, p);
    return rank;
}

/* -- newton.py: local Newton, full steps ------------------------------------------------------ */
static void newton(row_t *s, const opts_t *o) {
    double h[N * N], p[N], b[N], x_old[N];
    s->f = cost(s, s->x);
    grad(s, s->x, s->g);
    for (int k = 0; k < o->max_iter; ++k) {
        if (!isfinite(s->f) || !all_finite(s->g, N)) return stop(s, -1, k);
        if (gradient_small(s->g, s->f, o)) return stop(s, 1, k);
        hess(s, s->x, h);
        for (int i = 0; i < N; ++i) b[i] = -s->g[i];
        if (!solve(h, b, p) || !all_finite(p, N)) return stop(s, -1, k);
        memcpy(x_old, s->x, sizeof x_old);
        for (int i = 0; i < N; ++i) s->x[i] = x_old[i] + p[i];
        s->f = cost(s, s->x);
        grad(s, s->x, s->g);
        if (step_small(p, x_old, o)) return stop(s, 3, k + 1);
    }
    stop(s, 0, o->max_iter);
}

/* -- line_search.py: Armijo backtracking and the strong Wolfe search ------------------------------ */
static double along(row_t *s, const double *x, const double *p, double a, double *xt) {
    for (int i = 0; i < N; ++i) xt[i] = x[i] + a * p[i];
    return cost(s, xt);
}

static int armijo(row_t *s, const double *x, const double *p, double f0, double slope, double *alpha, double *value) {
    double xt[N], a = 1.0;
    for (int k = 0; k < 60; ++k) {
        double v = along(s, x, p, a, xt);
        if (isfinite(v) && v <= f0 + C1 * a * slope) { *alpha = a; *value = v; return 1; }
        a *= RHO_LS;
    }
    return 0;
}

static double slope_at(row_t *s, const double *x, const double *p, double a) {
    double xt[N], gt[N];
    for (int i = 0; i < N; ++i) xt[i] = x[i] + a * p[i];
    grad(s, xt, gt);
    return dot(gt, p, N);
}

/* line_search.wolfe for one row: bracketing (phase 0) doubles alpha, zooming (1) bisects */
static int wolfe(row_t *s, const double *x, const double *p, double f0, double slope, double *alpha, double *value) {
    const double alpha_max = 1e6;
    const int max_steps = 60;
    double xt[N], a = 1.0, prev_alpha = 0.0, prev_value = f0, lo = 0.0, hi = 0.0, f_lo = 0.0;
    int zoom = 0, steps = 0;
    for (;;) {
        double trial = zoom ? 0.5 * (lo + hi) : a;
        double v = along(s, x, p, trial, xt);
        int high = !isfinite(v) || v > f0 + C1 * trial * slope || (zoom ? v >= f_lo : (steps > 0 && v >= prev_value));
        double d = NAN;
        if (!high) d = slope_at(s, x, p, trial);
        if (!high && fabs(d) <= -C2 * slope) { *alpha = trial; *value = v; return 1; }
        if (!zoom) {
            if (high) { zoom = 1; lo = prev_alpha; hi = trial; f_lo = prev_value; steps = 0; }
            else if (d >= 0) { zoom = 1; lo = trial; hi = prev_alpha; f_lo = v; steps = 0; }
            else {
                prev_alpha = a; prev_value = v;
                a = nmin(2.0 * a, alpha_max);
                if (++steps >= max_steps) return 0;
            }
            continue;
        }
        if (high) hi = trial;
        else {
            if (d * (hi - lo) >= 0) hi = lo;
            lo = trial; f_lo = v;
        }
        if (++steps >= max_steps) {
            if (lo > 0) { *alpha = lo; *value = f_lo; return 1; }
            return 0;
        }
    }
}

/* line_search.bfgs's update of the inverse-Hessian approximation */
static void bfgs_update(double *h_inv, int *has, const double *st, const double *y) {
    double sy = dot(st, y, N), h0[N * N], v[N * N], t[N * N];
    if (!(sy > 1e-12 * norm(st, N) * norm(y, N))) return;
    double scale = sy / dot(y, y, N), rho = 1.0 / sy;
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j) {
            double eye = i == j ? 1.0 : 0.0;
            h0[N * i + j] = *has ? h_inv[N * i + j] : scale * eye;
            v[N * i + j] = eye - rho * (st[i] * y[j]);
        }
    for (int i = 0; i < N; ++i) /* t = v h0 */
        for (int j = 0; j < N; ++j) {
            double u = v[N * i] * h0[j];
            for (int k = 1; k < N; ++k) u += v[N * i + k] * h0[N * k + j];
            t[N * i + j] = u;
        }
    for (int i = 0; i < N; ++i) /* h = t v^T + rho s s^T */
        for (int j = 0; j < N; ++j) {
            double u = t[N * i] * v[N * j];
            for (int k = 1; k < N; ++k) u += t[N * i + k] * v[N * j + k];
            h_inv[N * i + j] = u + rho * (st[i] * st[j]);
        }
    *has = 1;
}

/* the search direction of damped Newton, steepest descent or BFGS (line_search._run's direction) */
static void direction(row_t *s, int method, const double *h_inv, int has, double *p) {
    double h[N * N], b[N];
    for (int i = 0; i < N; ++i) p[i] = -s->g[i];
    if (method == NEWTON_LS) {
        hess(s, s->x, h);
        for (int i = 0; i < N; ++i) b[i] = -s->g[i];
        if (!solve(h, b, p))
            for (int i = 0; i < N; ++i) p[i] = -s->g[i];
    } else if (method == BFGS && has) {
        matvec(h_inv, s->g, N, N, b);
        for (int i = 0; i < N; ++i) p[i] = -b[i];
    }
}

/* line_search._run for one row */
static void line_search(row_t *s, int method, const opts_t *o) {
    double p[N], step[N], x_old[N], g_new[N], y[N], h_inv[N * N] = {0}, alpha = 1.0, f_new = NAN;
    int has = 0;
    s->f = cost(s, s->x);
    grad(s, s->x, s->g);
    for (int k = 0; k < o->max_iter; ++k) {
        if (!isfinite(s->f) || !all_finite(s->g, N)) return stop(s, -1, k);
        if (gradient_small(s->g, s->f, o)) return stop(s, 1, k);
        direction(s, method, h_inv, has, p);
        double slope = dot(s->g, p, N);
        if (!all_finite(p, N) || slope >= 0) { /* not a descent direction: steepest descent */
            for (int i = 0; i < N; ++i) p[i] = -s->g[i];
            slope = -dot(s->g, s->g, N);
            has = 0;
        }
        int found = method == BFGS ? wolfe(s, s->x, p, s->f, slope, &alpha, &f_new)
                                   : armijo(s, s->x, p, s->f, slope, &alpha, &f_new);
        if (!found) {
            int precision = fabs(slope) <= 100 * EPS * nmax(1.0, fabs(s->f));
            s->msg = precision ? MSG_AT_PRECISION : MSG_NO_STEP;
            return stop(s, precision ? 2 : -1, k);
        }
        for (int i = 0; i < N; ++i) step[i] = alpha * p[i];
        memcpy(x_old, s->x, sizeof x_old);
        for (int i = 0; i < N; ++i) s->x[i] = x_old[i] + step[i];
        grad(s, s->x, g_new);
        if (method == BFGS) {
            for (int i = 0; i < N; ++i) y[i] = g_new[i] - s->g[i];
            bfgs_update(h_inv, &has, step, y);
        }
        double f_old = s->f;
        s->f = f_new;
        memcpy(s->g, g_new, sizeof g_new);
        if (step_small(step, x_old, o)) return stop(s, 3, k + 1);
        if (reduction_small(f_old, f_new, o)) return stop(s, 2, k + 1);
    }
    stop(s, 0, o->max_iter);
}

/* -- gauss_newton.py: full Gauss-Newton steps, minimum-norm where J is rank-deficient ------------- */
static void gauss_newton(row_t *s, const opts_t *o) {
    double r[M], j[M * N], p[N], b[M], x_old[N];
    resid(s, s->x, r);
    s->f = 0.5 * dot(r, r, M);
    for (int k = 0; k < o->max_iter; ++k) {
        jac(s, s->x, j);
        tmatvec(j, r, M, N, s->g);
        if (!isfinite(s->f) || !all_finite(j, M * N)) return stop(s, -1, k);
        if (gradient_small(s->g, s->f, o)) return stop(s, 1, k);
        for (int i = 0; i < M; ++i) b[i] = -r[i];
        if (lstsq(j, b, p) < N) s->rankdef++;
        if (!all_finite(p, N)) return stop(s, -1, k);
        double f_old = s->f;
        memcpy(x_old, s->x, sizeof x_old);
        for (int i = 0; i < N; ++i) s->x[i] = x_old[i] + p[i];
        resid(s, s->x, r);
        s->f = 0.5 * dot(r, r, M);
        int small_step = step_small(p, x_old, o);
        int reduced = !small_step && s->f <= f_old && reduction_small(f_old, s->f, o);
        if (small_step || reduced) { /* the gradient reported at a stop after a step (not counted) */
            call(he_g, s->x, s->g);
            return stop(s, small_step ? 3 : 2, k + 1);
        }
    }
    call(he_g, s->x, s->g);
    stop(s, 0, o->max_iter);
}

/* -- levenberg_marquardt.py: Marquardt's scaled damping, Nielsen's update ------------------------- */
static void lm_model(row_t *s, const double *r, double *j, double *a) {
    jac(s, s->x, j);
    gram(j, a);
    tmatvec(j, r, M, N, s->g);
}

static void levenberg_marquardt(row_t *s, const opts_t *o) {
    double r[M], r_new[M], j[M * N], a[N * N], d[N], damped[N * N], p[N], b[N], x_new[N];
    resid(s, s->x, r);
    s->f = 0.5 * dot(r, r, M);
    lm_model(s, r, j, a);
    double biggest = a[0], dmax;
    for (int i = 1; i < N; ++i) biggest = nmax(biggest, a[N * i + i]);
    for (int i = 0; i < N; ++i) d[i] = nmax(a[N * i + i], 1e-12 * nmax(1.0, biggest));
    dmax = d[0];
    for (int i = 1; i < N; ++i) dmax = nmax(dmax, d[i]);
    double mu = dmax > 0 ? o->lm_tau * biggest / dmax : o->lm_tau, nu = 2.0;
    for (int k = 0; k < o->max_iter; ++k) {
        if (!isfinite(s->f) || !all_finite(j, M * N)) return stop(s, -1, k);
        if (gradient_small(s->g, s->f, o)) return stop(s, 1, k);
        memcpy(damped, a, sizeof damped);
        for (int i = 0; i < N; ++i) damped[N * i + i] += mu * d[i];
        for (int i = 0; i < N; ++i) b[i] = -s->g[i];
        if (!solve(damped, b, p)) return stop(s, -1, k);
        if (step_small(p, s->x, o)) return stop(s, 3, k);
        for (int i = 0; i < N; ++i) x_new[i] = s->x[i] + p[i];
        resid(s, x_new, r_new);
        double f = s->f, f_new = 0.5 * dot(r_new, r_new, M);
        double predicted = -dot(s->g, p, N) - 0.5 * quad(p, a);
        double rho = predicted > 0 ? (f - f_new) / predicted : -1.0;
        if (isfinite(f_new) && rho > 0) { /* accepted: move, new model, less damping */
            memcpy(s->x, x_new, sizeof x_new);
            memcpy(r, r_new, sizeof r_new);
            s->f = f_new;
            lm_model(s, r, j, a);
            for (int i = 0; i < N; ++i) d[i] = nmax(d[i], a[N * i + i]);
            double c = 2.0 * rho - 1.0;
            mu *= nmax(1.0 / 3.0, 1.0 - pow(c, 3.0));
            nu = 2.0;
            if (reduction_small(f, f_new, o)) return stop(s, 2, k + 1);
        } else { /* rejected: more damping */
            mu *= nu;
            nu *= 2.0;
            if (mu > 1e30) return stop(s, -1, k + 1);
        }
    }
    stop(s, 0, o->max_iter);
}

/* -- trust_region.py: Newton model, More-Sorensen subproblem, scaled region -------------------- */
static double boundary_tau(const double *p, const double *d, double radius) {
    double a = dot(d, d, N), b = 2.0 * dot(p, d, N), c = dot(p, p, N) - radius * radius;
    return (-b + sqrt(nmax(b * b - 4 * a * c, 0.0))) / (2 * a);
}

/* The secular equation 1/|p(lam)| = 1/radius by safeguarded Newton steps (subproblem_exact's loop). */
static double secular(const double *w, const double *gt, double radius, double lo, double hi, double lam) {
    double q[N], t[N];
    for (int it = 0; it < 100; ++it) {
        double lam_r = (lo < lam && lam < hi) ? lam : 0.5 * (lo + hi);
        for (int i = 0; i < N; ++i) q[i] = gt[i] / (w[i] + lam_r);
        double pn = norm(q, N);
        if (fabs(pn - radius) <= 1e-10 * radius) return lam_r;
        double phi = 1.0 / pn - 1.0 / radius;
        double lo_r = phi < 0 ? lam_r : lo, hi_r = phi < 0 ? hi : lam_r;
        for (int i = 0; i < N; ++i) t[i] = q[i] * q[i] / (w[i] + lam_r);
        double dphi = dot_ones(t) / pow(pn, 3.0);
        lam = dphi > 0 ? lam_r - phi / dphi : 0.5 * (lo_r + hi_r);
        lo = lo_r;
        hi = hi_r;
    }
    return lam;
}

/* trust_region.subproblem_exact for one row (N&W Algorithm 4.3, in the eigenbasis of b) */
static void subproblem_exact(const double *g, const double *b, double radius, double *p) {
    double w[N], v[N * N], gt[N], u[N], inner[N];
    eigh(b, w, v);
    tmatvec(v, g, N, N, gt);
    double tiny = 1e-12 * nmax(1.0, max_abs(w, N));
    for (int i = 0; i < N; ++i) u[i] = gt[i] / w[i];
    matvec(v, u, N, N, p);
    for (int i = 0; i < N; ++i) p[i] = -p[i];
    if (w[0] > tiny && norm(p, N) <= radius) return;
    double lo = nmax(0.0, -w[0]);
    for (int i = 0; i < N; ++i) {
        int lowest = fabs(w[i] - w[0]) <= tiny;
        double denom = w[i] + lo;
        u[i] = lowest ? gt[i] : 0.0;
        inner[i] = (!lowest && fabs(denom) > tiny) ? gt[i] / denom : 0.0;
    }
    int hard = norm(u, N) <= 1e-10 * nmax(1.0, norm(g, N));
    matvec(v, inner, N, N, u);
    for (int i = 0; i < N; ++i) inner[i] = -u[i];
    if (hard && norm(inner, N) <= radius) { /* the hard case: to the boundary along the lowest eigenvector */
        double z[N];
        for (int i = 0; i < N; ++i) z[i] = v[N * i];
        double tau = boundary_tau(inner, z, radius);
        for (int i = 0; i < N; ++i) p[i] = inner[i] + tau * z[i];
        return;
    }
    double hi = lo + norm(g, N) / radius + tiny;
    double lam = secular(w, gt, radius, lo, hi, lo + tiny);
    for (int i = 0; i < N; ++i) u[i] = gt[i] / (w[i] + lam);
    matvec(v, u, N, N, p);
    for (int i = 0; i < N; ++i) p[i] = -p[i];
}

typedef struct {
    double b[N * N], diag[N], radius, max_radius, min_radius;
} region_t;

static void tr_model(row_t *s, region_t *t, int first, const opts_t *o) {
    s->f = cost(s, s->x);
    grad(s, s->x, s->g);
    hess(s, s->x, t->b);
    for (int i = 0; i < N; ++i) { /* the scaling D (trust_region.run's scale) */
        double d = o->scaling ? sqrt(fabs(t->b[N * i + i])) : 1.0;
        if (o->scaling && !first) d = nmax(t->diag[i], d);
        t->diag[i] = d > 0 ? d : 1.0;
    }
}

/* the scaled model g~ = D^-1 g, B~ = D^-1 B D^-1 */
static void scaled(const row_t *s, const region_t *t, double *gs, double *bs) {
    for (int i = 0; i < N; ++i) {
        gs[i] = s->g[i] / t->diag[i];
        for (int j = 0; j < N; ++j) bs[N * i + j] = t->b[N * i + j] / (t->diag[i] * t->diag[j]);
    }
}

static double cauchy_length(const double *g, const double *b) {
    double gg = dot(g, g, N), curv = quad(g, b);
    double length = curv > 0 ? pow(gg, 1.5) / curv : sqrt(gg);
    return isfinite(length) ? nmax(length, 1e-8) : 1.0;
}

static void trust_region(row_t *s, const opts_t *o) {
    region_t t;
    double gs[N], bs[N * N], ps[N], p[N], x_new[N], x_old[N];
    tr_model(s, &t, 1, o);
    scaled(s, &t, gs, bs);
    t.radius = o->initial_radius > 0 ? o->initial_radius : cauchy_length(gs, bs);
    t.max_radius = o->max_radius_factor * t.radius;
    t.min_radius = 1e-14 * t.radius;
    for (int k = 0; k < o->max_iter; ++k) {
        if (!isfinite(s->f) || !all_finite(s->g, N) || !all_finite(t.b, N * N)) return stop(s, -1, k);
        if (gradient_small(s->g, s->f, o)) return stop(s, 1, k);
        scaled(s, &t, gs, bs);
        subproblem_exact(gs, bs, t.radius, ps);
        for (int i = 0; i < N; ++i) p[i] = ps[i] / t.diag[i];
        double predicted = -(dot(s->g, p, N) + 0.5 * quad(p, t.b));
        for (int i = 0; i < N; ++i) x_new[i] = s->x[i] + p[i];
        double f = s->f, f_new = cost(s, x_new);
        double rho = predicted > 0 ? (f - f_new) / predicted : -1.0;
        double noise = 100 * EPS * nmax(1.0, fabs(f));
        if (predicted >= 0 && predicted <= noise && isfinite(f_new) && f_new <= f + noise) rho = 1.0;
        double pnorm = norm(ps, N);
        int shrink = !isfinite(f_new) || rho < 0.25;
        if (shrink) t.radius = 0.25 * pnorm;
        else if (rho > 0.75 && pnorm >= 0.999 * t.radius) t.radius = nmin(2.0 * t.radius, t.max_radius);
        if (isfinite(f_new) && rho > o->eta) {
            memcpy(x_old, s->x, sizeof x_old);
            memcpy(s->x, x_new, sizeof x_new);
            tr_model(s, &t, 0, o);
            if (step_small(p, x_old, o)) return stop(s, 3, k + 1);
            if (reduction_small(f, s->f, o)) return stop(s, 2, k + 1);
        } else if (t.radius < t.min_radius) {
            return stop(s, 4, k + 1);
        }
    }
    stop(s, 0, o->max_iter);
}

static void run_method(int method, row_t *s, const opts_t *o) {
    switch (method) {
    case NEWTON: newton(s, o); break;
    case NEWTON_LS: case SD: case BFGS: line_search(s, method, o); break;
    case GN: gauss_newton(s, o); break;
    case LM: levenberg_marquardt(s, o); break;
    default: trust_region(s, o);
    }
}

/* Run `method` from each of the n starts (x, n x N, overwritten by the ends); per row write the
 * cost f, the gradient g (n x N) and info (n x 7: iterations, nfev, njev, nhev, status, message,
 * rank-deficient steps). opt: max_iter, gtol, ftol, xtol, eta, lm_tau, max_radius_factor,
 * initial_radius (0: the Cauchy length), scaling. Returns 0, or -1 for an unknown method. */
int he_starts(int method, long n, const double *opt, double *x, double *f, double *g, double *info) {
    opts_t o = {(int)opt[0], opt[1], opt[2], opt[3], opt[4], opt[5], opt[6], opt[7], (int)opt[8]};
    if (method < NEWTON || method > TR) return -1;
    for (long i = 0; i < n; ++i) {
        row_t s;
        memset(&s, 0, sizeof s);
        memcpy(s.x, x + N * i, sizeof s.x);
        run_method(method, &s, &o);
        memcpy(x + N * i, s.x, sizeof s.x);
        memcpy(g + N * i, s.g, sizeof s.g);
        f[i] = s.f;
        double *in = info + 7 * i;
        in[0] = s.it; in[1] = s.nfev; in[2] = s.njev; in[3] = s.nhev; in[4] = s.status; in[5] = s.msg;
        in[6] = s.rankdef;
    }
    return 0;
}
