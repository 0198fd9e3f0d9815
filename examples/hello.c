/* hello.c - the smallest simcluster program: a ball falls onto a floor.
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
    for (int frame = 1; frame <= 100; frame++) {
        int rc = sc_world_step(w, 0.01);
        if (rc != SC_OK) {
            fprintf(stderr, "hello: %s\n", sc_strerror(rc));
            break;
        }
        sc_contact c;
        if (sc_world_contacts(w, &c, 1) > 0) {
            double p[3];
            sc_body_get_pose(w, id, p, NULL);
            printf("frame %d: ball touches the floor at z = %.3f m (depth %.4f m)\n",
                   frame, p[2], c.depth);
            break;
        }
    }
    sc_world_destroy(w);
    return 0;
}
