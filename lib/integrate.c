/* integrate.c - the paper's step 3: external forces on velocities before
 * the contact solve, positions after it. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "sc_internal.h"
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

/* Step 3, first half: u* = u + h (g + F/m), gyroscopic term, and the world
 * inverse inertia the contact solve needs. v0/w0 keep u for restitution. */
void sc_apply_forces(sc_world *w, double h)
{
    for (int i = 0; i < w->nbodies; i++) {
        sc_body *b = &w->bodies[i];
        if (!sc_body_movable(b))
            continue;
        v3_copy(b->v0, b->v);
        v3_copy(b->w0, b->w);
        double a[3], R[9], Rt[9], t[9];
        v3_madd(a, w->cfg.gravity, b->force, b->inv_mass);
        v3_madd(b->v, b->v, a, h);
        q_to_m3(R, b->q);
        m3_transpose(Rt, R);
        m3_mul(t, R, b->inv_inertia);
        m3_mul(b->iw, t, Rt);
        double wb[3], Iw[3], gyro[3], tb[3], dw[3];
        m3_tmulv(wb, R, b->w);
        m3_mulv(Iw, b->inertia, wb);
        v3_cross(gyro, wb, Iw);
        m3_tmulv(tb, R, b->torque);
        v3_sub(tb, tb, gyro);
        m3_mulv(dw, b->inv_inertia, tb);
        v3_madd(wb, wb, dw, h);
        m3_mulv(b->w, R, wb);
    }
}

/* Step 3, second half: positions. The trapezoid rule x += h (u0 + u') / 2
 * is exact for free fall and for a constant friction deceleration; a body
 * that collided this substep took its impulse at the start and then flew
 * under the external forces: x += h (u' - a h / 2). */
void sc_integrate_positions(sc_world *w, double h)
{
    for (int i = 0; i < w->nbodies; i++) {
        sc_body *b = &w->bodies[i];
        if (!sc_body_movable(b))
            continue;
        double step[3], avg_w[3];
        if (b->collided == 2) {
            double a[3];
            v3_madd(a, w->cfg.gravity, b->force, b->inv_mass);
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

