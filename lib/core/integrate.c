/* integrate.c - the paper's step 3: external forces on velocities before
 * the contact solve, positions after it. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"
#include "vecmath.h"

/* Rotate q by angle |w| h about w (exact for constant w). */
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

/* The gyroscopic term I dw/dt = -w x I w over h, in the body frame,
 * explicit. It does no work, but the explicit step gains energy, by about
 * (|w| h)^2 times the body's inertia anisotropy: negligible for most
 * bodies, and it blew a fast-spinning nut of the 1000-body drop up to
 * 1e264 rad/s in one frame. So when a step gains more than 0.1 %, w is
 * scaled back to the energy it had. (Implicit Euler instead loses energy:
 * 2.4% of the Table 1 scene's in 50 s. Plain explicit steps stay exactly
 * what they were for every body below the limit.) */
static void gyroscopic(double wb[3], const double I[9], const double inv_I[9], double h)
{
    double Iw[3], g[3], dw[3];
    m3_mulv(Iw, I, wb);
    double e0 = v3_dot(wb, Iw);
    v3_cross(g, wb, Iw);
    m3_mulv(dw, inv_I, g);
    v3_madd(wb, wb, dw, -h);
    m3_mulv(Iw, I, wb);
    double e1 = v3_dot(wb, Iw);
    if (e1 > 1.001 * e0 && isfinite(e1))
        v3_scale(wb, wb, sqrt(e0 / e1));
}

/* The bodies of a frame in tasks (each body written by one task only, so
 * the result does not depend on who ran which): with the executor's
 * runner from SHARE_MIN bodies on, CHUNKS tasks; else one, here. */
#define SHARE_MIN 256
#define CHUNKS 8

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
    p->chunks = r && p->f->st->nbodies >= SHARE_MIN ? CHUNKS : 1;
    if (p->chunks > 1)
        r->run(r->ctx, body_task, p, p->chunks, NULL);
    else
        body_task(p, 0, NULL, 0);
}

/* Step 3, first half: u* = u + h (g + F/m), gyroscopic term, and the world
 * inverse inertia the contact solve needs. v0/w0 keep u for restitution. */
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
        double wb[3], tb[3], dw[3];
        m3_tmulv(wb, R, b->w);
        gyroscopic(wb, b->inertia, b->inv_inertia, h);
        m3_tmulv(tb, R, b->torque);
        m3_mulv(dw, b->inv_inertia, tb);
        v3_madd(wb, wb, dw, h);
        m3_mulv(b->w, R, wb);
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
 * under the external forces: x += h (u' - a h / 2). */
static void integrate_positions(const body_pass *p, int i0, int i1)
{
    sc_frame *f = p->f;
    double h = p->h;
    const unsigned char *only = p->only;
    for (int i = i0; i < i1; i++) {
        sc_body *b = &f->st->bodies[i];
        if (!sc_body_movable(b) || (only && !only[i]))
            continue;
        double step[3], avg_w[3];
        if (b->collided == 2) {
            double a[3];
            v3_madd(a, f->cfg->gravity, b->force, b->inv_mass);
            v3_madd(step, b->v, a, -0.5 * h);
            v3_copy(avg_w, b->w);
            b->collided = 1;
        } else {
            v3_add(step, b->v0, b->v);
            v3_scale(step, step, 0.5);
            v3_add(avg_w, b->w0, b->w);
            v3_scale(avg_w, avg_w, 0.5);
        }
        v3_madd(b->x, b->x, step, h);
        rotate_by(b->q, avg_w, h);
    }
}

void sc_integrate_positions(sc_frame *f, double h, const unsigned char *only)
{
    body_pass p = { .f = f, .h = h, .only = only, .fn = integrate_positions };
    run_pass(&p);
}
