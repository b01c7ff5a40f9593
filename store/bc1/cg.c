/* store/bc1/cg.c - the bounded, Jacobi-preconditioned conjugate-gradient solver of cg.h.
 *
 * Owns: the iteration (r = b - A x, z = M^-1 r, p, q = A p in the caller's workspace), the
 * projection rounds and the cancel check. Does not own: the matrix, the diagonal, memory.
 * Rows of fixed variables are zero in A and b (their value still enters the other rows through
 * the caller's product), so CG runs on the free variables only.
 */
#include "cg.h"

#include <string.h>

/* y = A x with the rows of fixed variables zeroed (fixed NULL: none). */
static void product(const st_cg *P, const uint8_t *fixed, const double *x, double *y)
{
    P->matvec(P->ctx, x, y);
    if (fixed)
        for (uint32_t i = 0; i < P->n; i++)
            if (fixed[i])
                y[i] = 0;
}

/* One CG solve over the free variables from the current x. */
static int solve_free(const st_cg *P, const uint8_t *fixed, double *x, double *wk)
{
    uint32_t n = P->n;
    double *r = wk, *z = wk + n, *p = wk + 2 * n, *q = wk + 3 * n;
    const double *minv = P->minv;
    product(P, fixed, x, q);
    double bnorm = 0, rz = 0;
    for (uint32_t i = 0; i < n; i++) {
        double b = (fixed && fixed[i]) ? 0 : P->b[i];
        r[i] = b - q[i];
        bnorm += b * b;
        z[i] = minv[i] * r[i];
        p[i] = z[i];
        rz += r[i] * z[i];
    }
    double tol = P->tol * (bnorm > 1 ? bnorm : 1);
    for (int it = 0; it < P->maxit; it++) {
        double rr = 0;
        for (uint32_t i = 0; i < n; i++)
            rr += r[i] * r[i];
        if (rr <= tol)
            break;
        if (P->cancel && __atomic_load_n(P->cancel, __ATOMIC_RELAXED))
            return 1;
        product(P, fixed, p, q);
        double pq = 0;
        for (uint32_t i = 0; i < n; i++)
            pq += p[i] * q[i];
        if (!(pq > 0))
            break;
        double a = rz / pq, rz2 = 0;
        for (uint32_t i = 0; i < n; i++) {
            x[i] += a * p[i];
            r[i] -= a * q[i];
            z[i] = minv[i] * r[i];
            rz2 += r[i] * z[i];
        }
        double beta = rz2 / rz;
        rz = rz2;
        for (uint32_t i = 0; i < n; i++)
            p[i] = z[i] + beta * p[i];
    }
    return 0;
}

int st_cg_solve(const st_cg *P, double *x, uint8_t *fixed, double *wk)
{
    memset(fixed, 0, P->n);
    for (int round = 0; round < P->rounds; round++) {
        if (solve_free(P, round ? fixed : NULL, x, wk))
            return 1;
        /* fix what left [lo, hi] at the bound, solve the rest again */
        int changed = 0;
        for (uint32_t i = 0; i < P->n; i++)
            if (x[i] < P->lo || x[i] > P->hi) {
                x[i] = x[i] < P->lo ? P->lo : P->hi;
                changed |= !fixed[i];
                fixed[i] = 1;
            }
        if (!changed)
            break;
    }
    return 0;
}
