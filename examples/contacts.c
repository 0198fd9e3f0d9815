/* contacts.c - drops a sphere, a box, a bolt and a nut onto a
 * floor and prints, frame by frame, the contacts the engine finds,
 * until every body has touched the floor. */
#include <stdio.h>

#include "simcluster.h"

#define NSHAPES 4

int main(void)
{
    sc_world *w = sc_world_create(NULL);
    if (!w) {
        fprintf(stderr, "contacts: %s\n", sc_strerror(sc_last_error()));
        return 1;
    }
    const char *names[NSHAPES + 1] = { "floor", "sphere", "box", "bolt", "nut" };
    sc_shape *shapes[NSHAPES + 1] = {
        sc_shape_plane(0, 0, 1, 0), sc_shape_uv_sphere(0.05, 16, 8),
        sc_shape_box(0.04, 0.03, 0.02), sc_shape_bolt(), sc_shape_nut()
    };
    for (int i = 0; i <= NSHAPES; i++) {
        if (!shapes[i]) {
            fprintf(stderr, "contacts: %s: %s\n", names[i], sc_strerror(sc_last_error()));
            return 1;
        }
        sc_body_desc d = sc_body_desc_default();
        d.shape = shapes[i];
        d.mass = i == 0 ? 0 : SC_MASS_FROM_DENSITY;
        d.density = 7800;                          /* steel */
        if (i > 0) {
            d.pos[0] = 0.15 * (i - 2.5);
            d.pos[2] = 0.1 + 0.05 * i;
        }
        d.quat[0] = 0.9238795;                     /* tilted 45 degrees about x */
        d.quat[1] = i == 0 ? 0 : 0.3826834;
        if (i == 0)
            d.quat[0] = 1;
        d.omega[2] = 2.0 * i;
        int id = sc_body_add(w, &d);
        if (id < 0) {
            fprintf(stderr, "contacts: %s: %s\n", names[i], sc_strerror(id));
            return 1;
        }
        sc_mass_props mp;
        if (i > 0 && sc_shape_mass_props(shapes[i], &mp) == SC_OK)
            printf("body %d %-6s %3d triangles, %.1f g\n", id, names[i],
                   sc_shape_triangles(shapes[i]), 1000 * 7800 * mp.volume);
        sc_shape_release(shapes[i]);
    }
    int touched[NSHAPES + 1] = { 0 }, ntouched = 0;
    const double dt = 0.01;
    for (int frame = 1; frame <= 100 && ntouched < NSHAPES; frame++) {
        int rc = sc_world_step(w, dt);
        if (rc != SC_OK) {
            fprintf(stderr, "contacts: step: %s\n", sc_strerror(rc));
            return 1;
        }
        sc_contact c[64];
        int n = sc_world_contacts(w, c, 64);
        if (n == 0)
            continue;
        printf("frame %3d  t = %.2f s  %d contact(s)\n", frame, frame * dt, n);
        for (int k = 0; k < n && k < 64; k++) {
            printf("  %-6s / %-6s at (%+.4f %+.4f %+.4f) normal (%+.3f %+.3f %+.3f) "
                   "depth %.2f mm\n", names[c[k].body_a], names[c[k].body_b], c[k].pos[0],
                   c[k].pos[1], c[k].pos[2], c[k].normal[0], c[k].normal[1], c[k].normal[2],
                   1000 * c[k].depth);
            int other = c[k].body_a == 0 ? c[k].body_b : c[k].body_a;
            if (!touched[other]) {
                touched[other] = 1;
                ntouched++;
            }
        }
    }
    sc_stats s;
    sc_world_stats(w, &s);
    printf("%ld frames, broad phase %.3f ms, narrow phase %.3f ms CPU in all\n", s.total.frames,
           1000 * s.total.stage_s[SC_STAGE_BROADPHASE],
           1000 * s.total.stage_s[SC_STAGE_NARROWPHASE]);
    sc_world_destroy(w);
    return ntouched == NSHAPES ? 0 : 1;
}
