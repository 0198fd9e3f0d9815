/* integrate.c - the paper's step 3: external forces on velocities before
 * the contact solve, positions after it. */
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"
#include "vecmath.h"

/* Free rotation (docs/DESIGN.md 3.6). A torque-free body keeps its
 * angular momentum L in the world and its kinetic energy; its angular
 * velocity turns as its inertia does. The step is the implicit midpoint
 * rule on Euler's equations in the body frame, pi' = pi + h pi_m x
 * I^-1 pi_m (pi = I w_body, pi_m the mean of pi and pi'), with the
 * orientation turned by the Cayley rotation of h I^-1 pi_m: then pi' is
 * that rotation's inverse applied to pi, so L = R pi is kept exactly, and
 * the midpoint rule keeps the quadratic invariants |pi|^2 and
 * pi . I^-1 pi, so the energy too. (An explicit gyroscopic step in the
 * body frame, with the orientation turned by exp(h w) after it, gains
 * energy on slow spins and loses it on fast ones: a fast tumbling part
 * loses most of its energy within a second.) */
#define ROT_STEP 0.5          /* rad: the implicit step converges fast below */
#define ROT_MAX_PARTS 64
#define ROT_MAX_ITER 100

/* The body of inverse inertia inv_I at orientation q (its matrix R)
 * turning freely with the world angular momentum L for h: q turned. 0, or
 * -1 when the iteration did not converge (q then turned by the body's
 * angular velocity alone). */
static int free_rotation(double q[4], const double R[9], const double inv_I[9], const double L[3],
                         double h)
{
    double pi[3], om[3];
    m3_tmulv(pi, R, L);
    m3_mulv(om, inv_I, pi);
    double rate = v3_len(om) * h;
    if (!(rate > 0) || !isfinite(rate))
        return rate == 0 ? 0 : -1;
    int parts = (int)fmin(ceil(rate / ROT_STEP), ROT_MAX_PARTS);
    /* Newton's method on g(p) = p - pi - hs pm x I^-1 pm, pm = (pi + p)/2,
     * from the explicit step: its error e shrinks to about
     * (hs |I^-1| / 4) e^2 a step, so after a step of at most 3e-8 |pi| it
     * is of order 1e-15 |pi| (hs |I^-1 pi| <= ROT_STEP). Two steps where
     * the fixed-point iteration took ten (docs/DESIGN.md 3.6). */
    double hs = h / parts, tol2 = 1e-15 * v3_dot(pi, pi);
    int ok = 1;
    for (int k = 0; k < parts && ok; k++) {
        double p1[3], pm[3], cross[3];
        m3_mulv(om, inv_I, pi);
        v3_cross(cross, pi, om);
        v3_madd(p1, pi, cross, hs);
        ok = 0;
        for (int it = 0; it < ROT_MAX_ITER; it++) {
            double g[3], J[9], d[3];
            v3_add(pm, pi, p1);
            v3_scale(pm, pm, 0.5);
            m3_mulv(om, inv_I, pm);
            v3_cross(cross, pm, om);
            /* -g */
            for (int r = 0; r < 3; r++)
                g[r] = pi[r] + hs * cross[r] - p1[r];
            /* J = 1 - hs/2 ([pm]x I^-1 - [om]x) */
            double c = 0.5 * hs;
            for (int col = 0; col < 3; col++) {
                const double e[3] = { inv_I[col], inv_I[3 + col], inv_I[6 + col] };
                double mc[3];
                v3_cross(mc, pm, e);
                J[col] = -c * mc[0];
                J[3 + col] = -c * mc[1];
                J[6 + col] = -c * mc[2];
            }
            /* + c [om]x */
            J[1] += -c * om[2];
            J[2] += c * om[1];
            J[3] += c * om[2];
            J[5] += -c * om[0];
            J[6] += -c * om[1];
            J[7] += c * om[0];
            J[0] += 1;
            J[4] += 1;
            J[8] += 1;
            double Ji[9];
            if (!m3_inverse(Ji, J))
                break;
            m3_mulv(d, Ji, g);
            v3_add(p1, p1, d);
            if (v3_dot(d, d) <= tol2) {
                ok = 1;
                break;
            }
        }
        if (!ok)
            break;
        v3_add(pm, pi, p1);
        v3_scale(pm, pm, 0.5);
        m3_mulv(om, inv_I, pm);
        double w = v3_len(om);
        if (w > 0) {
            double axis[3], cq[4];
            v3_scale(axis, om, 1 / w);
            q_from_axis_angle(cq, axis, 2 * atan(0.5 * hs * w));
            q_mul(q, q, cq);          /* in the body frame: on the right */
        }
        v3_copy(pi, p1);
    }
    q_normalize(q);
    return ok ? 0 : -1;
}

/* Rotate q by angle |w| h about w (world frame; exact for constant w). */
static void rotate_by(double q[4], const double w[3], double h)
{
    double ang = v3_len(w) * h;
    if (ang == 0)
        return;
    double axis[3], dq[4];
    v3_scale(axis, w, h / ang);
    q_from_axis_angle(dq, axis, ang);
    q_mul(q, dq, q);
    q_normalize(q);
}

/* L = R I R^T w, the world angular momentum of angular velocity w (world)
 * for the body's orientation R (the inertia per the body's own units). */
static void momentum(double L[3], const double R[9], const double I[9], const double w[3])
{
    double wb[3], Ib[3];
    m3_tmulv(wb, R, w);
    m3_mulv(Ib, I, wb);
    m3_mulv(L, R, Ib);
}

/* The bodies of a frame in tasks (each body written by one task only, so
 * the result does not depend on who ran which): with the executor's
 * runner from SC_SHARE_MIN bodies on, SC_SHARE_CHUNKS tasks; else one,
 * here. */

typedef struct body_pass {
    sc_frame *f;
    double h;
    const unsigned char *only;
    int chunks;
    void (*fn)(const struct body_pass *p, int i0, int i1);
} body_pass;

static void body_task(void *arg, int t, sc_arena *a, int helper)
{
    (void)a;
    (void)helper;
    const body_pass *p = arg;
    long long n = p->f->st->nbodies;
    p->fn(p, (int)(n * t / p->chunks), (int)(n * (t + 1) / p->chunks));
}

static void run_pass(body_pass *p)
{
    const sc_task_runner *r = p->f->ex ? p->f->ex->runner : NULL;
    p->chunks = r && p->f->st->nbodies >= SC_SHARE_MIN ? SC_SHARE_CHUNKS : 1;
    sc_tasks_run(r, body_task, p, p->chunks, NULL);
}

/* Step 3, first half: u* = u + h (g + F/m), w* = w + h I^-1 torque, and
 * the world inverse inertia the contact solve needs. v0/w0 keep u for
 * restitution. How a free body's w turns with its inertia over the step
 * is the positions' part (free_rotation()): the contact solve sees the
 * momentum the body has at its pose now. */
static void apply_forces(const body_pass *p, int i0, int i1)
{
    sc_frame *f = p->f;
    double h = p->h;
    const unsigned char *only = p->only;
    for (int i = i0; i < i1; i++) {
        sc_body *b = &f->st->bodies[i];
        if (!sc_body_movable(b) || (only && !only[i]))
            continue;
        v3_copy(b->v0, b->v);
        v3_copy(b->w0, b->w);
        double a[3], R[9], Rt[9], t[9];
        v3_madd(a, f->cfg->gravity, b->force, b->inv_mass);
        v3_madd(b->v, b->v, a, h);
        q_to_m3(R, b->q);
        m3_transpose(Rt, R);
        m3_mul(t, R, b->inv_inertia);
        m3_mul(b->iw, t, Rt);
        double dw[3];
        m3_mulv(dw, b->iw, b->torque);
        v3_madd(b->w, b->w, dw, h);
    }
}

void sc_apply_forces(sc_frame *f, double h, const unsigned char *only)
{
    body_pass p = { .f = f, .h = h, .only = only, .fn = apply_forces };
    run_pass(&p);
}

/* Step 3, second half: positions. The trapezoid rule x += h (u0 + u') / 2
 * is exact for free fall and for a constant friction deceleration; a body
 * that collided this substep took its impulse at the start and then flew
 * under the external forces: x += h (u' - a h / 2). Orientations turn
 * freely (free_rotation()) with the mean of the angular momenta before
 * and after (L0 = I w0, L' = I w' at the pose the solve saw), or with L'
 * for a body that collided; the body ends with the angular momentum L'
 * at its new pose, w = R' I^-1 R'^T L'. Free flight so keeps L and the
 * energy exactly. */
static void integrate_positions(const body_pass *p, int i0, int i1)
{
    sc_frame *f = p->f;
    double h = p->h;
    const unsigned char *only = p->only;
    for (int i = i0; i < i1; i++) {
        sc_body *b = &f->st->bodies[i];
        if (!sc_body_movable(b) || (only && !only[i]))
            continue;
        double step[3], R[9], L1[3], Lrot[3];
        q_to_m3(R, b->q);
        momentum(L1, R, b->inertia, b->w);
        if (b->collided == 2) {
            double a[3];
            v3_madd(a, f->cfg->gravity, b->force, b->inv_mass);
            v3_madd(step, b->v, a, -0.5 * h);
            v3_copy(Lrot, L1);
            b->collided = 1;
        } else {
            v3_add(step, b->v0, b->v);
            v3_scale(step, step, 0.5);
            momentum(Lrot, R, b->inertia, b->w0);
            v3_add(Lrot, Lrot, L1);
            v3_scale(Lrot, Lrot, 0.5);
        }
        v3_madd(b->x, b->x, step, h);
        double q0[4];
        memcpy(q0, b->q, sizeof q0);
        if (free_rotation(b->q, R, b->inv_inertia, Lrot, h) != 0) {
            /* no convergence (a spin far past any real one): turned by
             * its angular velocity, which keeps it as it is */
            memcpy(b->q, q0, sizeof q0);
            double avg_w[3];
            m3_mulv(avg_w, b->iw, Lrot);
            rotate_by(b->q, avg_w, h);
            continue;
        }
        /* w' from L' at the new pose */
        double R1[9], lb[3], wb[3];
        q_to_m3(R1, b->q);
        m3_tmulv(lb, R1, L1);
        m3_mulv(wb, b->inv_inertia, lb);
        m3_mulv(b->w, R1, wb);
    }
}

void sc_integrate_positions(sc_frame *f, double h, const unsigned char *only)
{
    body_pass p = { .f = f, .h = h, .only = only, .fn = integrate_positions };
    run_pass(&p);
}
