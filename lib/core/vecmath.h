/* vecmath.h - small inline 3-vector, 3x3 matrix and quaternion helpers.
 * Quaternions are (w, x, y, z); matrices row-major. */
#ifndef SC_VECMATH_H
#define SC_VECMATH_H

#include <math.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

static inline void v3_set(double r[3], double x, double y, double z) { r[0] = x; r[1] = y; r[2] = z; }
static inline void v3_copy(double r[3], const double a[3]) { r[0] = a[0]; r[1] = a[1]; r[2] = a[2]; }
static inline void v3_add(double r[3], const double a[3], const double b[3])
{ r[0] = a[0] + b[0]; r[1] = a[1] + b[1]; r[2] = a[2] + b[2]; }
static inline void v3_sub(double r[3], const double a[3], const double b[3])
{ r[0] = a[0] - b[0]; r[1] = a[1] - b[1]; r[2] = a[2] - b[2]; }
static inline void v3_scale(double r[3], const double a[3], double s)
{ r[0] = a[0] * s; r[1] = a[1] * s; r[2] = a[2] * s; }
/* r = a + s b */
static inline void v3_madd(double r[3], const double a[3], const double b[3], double s)
{ r[0] = a[0] + s * b[0]; r[1] = a[1] + s * b[1]; r[2] = a[2] + s * b[2]; }
static inline double v3_dot(const double a[3], const double b[3])
{ return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
#ifdef __SSE2__
/* Two v3_dot(n, p) at once: n's components broadcast in x, y, z, the two
 * points from a pair block x0 x1 y0 y1 z0 z1 (sc_soa_pairs()); the same
 * products summed in the same order, so the same bits as v3_dot(). */
static inline __m128d v3_dot2(__m128d x, __m128d y, __m128d z, const double *pair)
{
    return _mm_add_pd(_mm_add_pd(_mm_mul_pd(x, _mm_loadu_pd(pair)),
                                 _mm_mul_pd(y, _mm_loadu_pd(pair + 2))),
                      _mm_mul_pd(z, _mm_loadu_pd(pair + 4)));
}
#endif
static inline void v3_cross(double r[3], const double a[3], const double b[3])
{
    double x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2],
           z = a[0] * b[1] - a[1] * b[0];
    r[0] = x; r[1] = y; r[2] = z;
}
static inline double v3_len(const double a[3]) { return sqrt(v3_dot(a, a)); }
static inline double v3_dist(const double a[3], const double b[3])
{ double d[3]; v3_sub(d, a, b); return v3_len(d); }
/* Normalise in place; returns the old length (0 leaves a unchanged). */
static inline double v3_normalize(double a[3])
{
    double l = v3_len(a);
    if (l > 0) v3_scale(a, a, 1.0 / l);
    return l;
}

/* n = the unit normal of triangle a b c (counter-clockwise: right hand);
 * returns twice its area (0 leaves n the zero vector) */
static inline double tri_normal(double n[3], const double a[3], const double b[3],
                                const double c[3])
{
    double e1[3], e2[3];
    v3_sub(e1, b, a);
    v3_sub(e2, c, a);
    v3_cross(n, e1, e2);
    return v3_normalize(n);
}

/* r = m v */
static inline void m3_mulv(double r[3], const double m[9], const double v[3])
{
    double x = m[0] * v[0] + m[1] * v[1] + m[2] * v[2];
    double y = m[3] * v[0] + m[4] * v[1] + m[5] * v[2];
    double z = m[6] * v[0] + m[7] * v[1] + m[8] * v[2];
    r[0] = x; r[1] = y; r[2] = z;
}
/* r = m^T v */
static inline void m3_tmulv(double r[3], const double m[9], const double v[3])
{
    double x = m[0] * v[0] + m[3] * v[1] + m[6] * v[2];
    double y = m[1] * v[0] + m[4] * v[1] + m[7] * v[2];
    double z = m[2] * v[0] + m[5] * v[1] + m[8] * v[2];
    r[0] = x; r[1] = y; r[2] = z;
}
/* r = a b */
static inline void m3_mul(double r[9], const double a[9], const double b[9])
{
    double t[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            t[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
    for (int i = 0; i < 9; i++) r[i] = t[i];
}
static inline void m3_transpose(double r[9], const double a[9])
{
    double t[9] = { a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8] };
    for (int i = 0; i < 9; i++) r[i] = t[i];
}
/* Inverse of a symmetric positive definite 3x3 (inertia); returns 0 if singular. */
static inline int m3_inverse(double r[9], const double m[9])
{
    double c0 = m[4] * m[8] - m[5] * m[7], c1 = m[5] * m[6] - m[3] * m[8],
           c2 = m[3] * m[7] - m[4] * m[6];
    double det = m[0] * c0 + m[1] * c1 + m[2] * c2;
    if (!(fabs(det) > 0) || !isfinite(det)) return 0;
    double id = 1.0 / det, t[9];
    t[0] = c0 * id; t[1] = (m[2] * m[7] - m[1] * m[8]) * id; t[2] = (m[1] * m[5] - m[2] * m[4]) * id;
    t[3] = c1 * id; t[4] = (m[0] * m[8] - m[2] * m[6]) * id; t[5] = (m[2] * m[3] - m[0] * m[5]) * id;
    t[6] = c2 * id; t[7] = (m[1] * m[6] - m[0] * m[7]) * id; t[8] = (m[0] * m[4] - m[1] * m[3]) * id;
    for (int i = 0; i < 9; i++) r[i] = t[i];
    return 1;
}

static inline void q_identity(double q[4]) { q[0] = 1; q[1] = q[2] = q[3] = 0; }
/* r = a b (apply b, then a) */
static inline void q_mul(double r[4], const double a[4], const double b[4])
{
    double w = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
    double x = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
    double y = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
    double z = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
    r[0] = w; r[1] = x; r[2] = y; r[3] = z;
}
static inline double q_dot(const double a[4], const double b[4])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
}
static inline double q_normalize(double q[4])
{
    double l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (l > 0) { q[0] /= l; q[1] /= l; q[2] /= l; q[3] /= l; }
    return l;
}
/* Rotation matrix of a unit quaternion. */
static inline void q_to_m3(double m[9], const double q[4])
{
    double w = q[0], x = q[1], y = q[2], z = q[3];
    m[0] = 1 - 2 * (y * y + z * z); m[1] = 2 * (x * y - w * z);     m[2] = 2 * (x * z + w * y);
    m[3] = 2 * (x * y + w * z);     m[4] = 1 - 2 * (x * x + z * z); m[5] = 2 * (y * z - w * x);
    m[6] = 2 * (x * z - w * y);     m[7] = 2 * (y * z + w * x);     m[8] = 1 - 2 * (x * x + y * y);
}
/* r = rotate v by unit quaternion q */
static inline void q_rotate(double r[3], const double q[4], const double v[3])
{
    double m[9];
    q_to_m3(m, q);
    m3_mulv(r, m, v);
}
/* Quaternion of a rotation by angle (rad) about a unit axis. */
static inline void q_from_axis_angle(double q[4], const double axis[3], double angle)
{
    double s = sin(0.5 * angle);
    q[0] = cos(0.5 * angle); q[1] = axis[0] * s; q[2] = axis[1] * s; q[3] = axis[2] * s;
}
/* Spherical interpolation between unit quaternions, shortest arc. */
static inline void q_slerp(double r[4], const double a[4], const double b0[4], double t)
{
    double b[4] = { b0[0], b0[1], b0[2], b0[3] };
    double c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
    if (c < 0) { c = -c; for (int i = 0; i < 4; i++) b[i] = -b[i]; }
    double wa, wb;
    if (c > 0.9995) {             /* nearly parallel: nlerp is exact enough */
        wa = 1 - t; wb = t;
    } else {
        double th = acos(c), s = sin(th);
        wa = sin((1 - t) * th) / s; wb = sin(t * th) / s;
    }
    for (int i = 0; i < 4; i++) r[i] = wa * a[i] + wb * b[i];
    q_normalize(r);
}
/* Angle (rad, in [0, pi]) of the rotation from a to b. */
static inline double q_angle_between(const double a[4], const double b[4])
{
    double c = fabs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]);
    return 2.0 * acos(c > 1 ? 1 : c);
}

#endif /* SC_VECMATH_H */
