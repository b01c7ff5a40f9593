/* store/bc1/cg.h - one bounded, Jacobi-preconditioned conjugate-gradient solver for the
 * store's sparse symmetric positive (semi-)definite systems: seam masking (seammask.c) and
 * the seam-aware endpoint solve (bc1_seam.c).
 *
 * Owns: the CG iteration, its stopping rule, the projection onto bounds (variables that leave
 * [lo, hi] are fixed at the bound and the rest solved again, up to `rounds` times) and the
 * cancel check between iterations. Does not own: the matrix (a caller's callback), the
 * diagonal, any memory (the caller passes a workspace) or error messages (the caller names
 * the cancelled operation).
 * Pure: no allocation, no globals; deterministic (the sums run in index order).
 */
#ifndef ST_BC1_CG_H
#define ST_BC1_CG_H

#include <stdint.h>

/* y = A x over all n variables (the solver zeroes the rows of fixed variables). */
typedef void (*st_cg_matvec_fn)(void *ctx, const double *x, double *y);

typedef struct st_cg {
    uint32_t        n;
    st_cg_matvec_fn matvec;
    void           *ctx;       /* passed to matvec */
    const double   *minv;      /* n: the Jacobi preconditioner, 1 / diag(A) (0: none) */
    const double   *b;         /* n: the right-hand side */
    double          lo, hi;    /* bounds on every variable */
    int             rounds;    /* bounded rounds (>= 1): solve, fix at the bounds, again */
    double          tol;       /* relative: stop when |r|^2 <= tol * max(|b_free|^2, 1) */
    int             maxit;     /* iterations per round */
    const volatile int *cancel; /* NULL, or read before every iteration */
} st_cg;

/* Solves A x = b for x in [lo, hi]^n, x warm-started by the caller (in: the start, out: the
 * solution). fixed: n bytes of caller-owned scratch (cleared here; on return 1 marks the
 * variables held at a bound). wk: 4n doubles of caller-owned scratch. Returns 0, or 1 when
 * *cancel became non-zero (x is then a partial solution). */
int st_cg_solve(const st_cg *P, double *x, uint8_t *fixed, double *wk);

#endif
