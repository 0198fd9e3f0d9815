/* hello.c - the smallest simcluster program: a ball falls 0.9 m onto a
 * floor, bounces and comes to rest; it prints what happens when.
 * Build against an installed library:
 *   cc hello.c -o hello $(pkg-config --cflags --libs simcluster) */
#include <stdio.h>

#include <simcluster.h>

int main(void)
{
    sc_world *w = sc_world_create(NULL);
    if (!w) {
        fprintf(stderr, "hello: %s\n", sc_strerror(sc_last_error()));
        return 1;
    }
    sc_shape *floor = sc_shape_plane(0, 0, 1, 0);
    sc_shape *ball = sc_shape_sphere(0.1);
    sc_body_desc d = sc_body_desc_default();
    d.shape = floor;
    d.mass = 0;
    sc_body_add(w, &d);
    d = sc_body_desc_default();
    d.shape = ball;
    d.mass = 1.0;
    d.pos[2] = 1.0;
    int id = sc_body_add(w, &d);
    sc_shape_release(floor);            /* the world keeps its own references */
    sc_shape_release(ball);
    if (id < 0) {
        fprintf(stderr, "hello: %s\n", sc_strerror(id));
        sc_world_destroy(w);
        return 1;
    }
    /* Step until the ball rests (at most 10 s): print each change of its
     * state, the height at each touch-down, and the top of each bounce
     * (with e = 0.5 each is a quarter of the one before). */
    static const char *names[] = { "in free flight", "colliding", "in contact", "asleep",
                                   "static" };
    int state = sc_body_state(w, id), rising = 0;
    double last_z = 1.0;
    printf("t 0.00 s: ball %s at z = %.3f m\n", names[state], last_z);
    for (int frame = 1; frame <= 1000 && state != SC_ASLEEP; frame++) {
        int rc = sc_world_step(w, 0.01);
        if (rc != SC_OK) {
            fprintf(stderr, "hello: %s\n", sc_strerror(rc));
            break;
        }
        double p[3];
        sc_body_get_pose(w, id, p, NULL);
        if (rising && p[2] < last_z && state == SC_FREE)   /* the top of a bounce */
            printf("t %.2f s: bounced up to z = %.3f m (%.1f mm above the floor)\n",
                   (frame - 1) * 0.01, last_z, 1e3 * (last_z - 0.1));
        rising = p[2] > last_z;
        last_z = p[2];
        int s = sc_body_state(w, id);
        if (s != state && s >= 0 && s <= SC_STATIC) {
            printf("t %.2f s: ball %s at z = %.3f m\n", frame * 0.01, names[s], p[2]);
            state = s;
        }
    }
    sc_world_destroy(w);
    return 0;
}
