/* state.c - the paper's body states (free fall, collision, contact) and
 * sleep: islands that stay slow stop costing CPU until touched. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"
#include "vecmath.h"

#define SLEEP_SPEED 0.02      /* m/s: a body whose centre and whose farthest
                                 point (its turn times its bounding radius)
                                 both move slower is slow */
#define SLEEP_TIME 0.5        /* s an island stays slow before it sleeps */

/* The paper's states: free fall, collision, contact; islands that stay slow
 * go to sleep and cost nothing until touched. */
void sc_update_states(sc_frame *f, const sc_islands *is, const unsigned char *touched,
                      double dt)
{
    for (int i = 0; i < f->st->nbodies; i++) {
        sc_body *b = &f->st->bodies[i];
        if (!sc_body_movable(b))
            continue;
        /* the turn by its reach, not in rad/s: a threshold in rad/s keeps
         * a long part whose ends barely creep awake, and its pile with it */
        int slow = v3_len(b->v) < SLEEP_SPEED && v3_len(b->w) * b->shape->bound_r < SLEEP_SPEED;
        b->rest_s = slow && touched[i] ? b->rest_s + dt : 0;
        b->state = b->collided ? SC_COLLIDING : (touched[i] ? SC_CONTACT : SC_FREE);
        b->collided = 0;
    }
    for (int k = 0; k < is->count; k++) {
        double rest = INFINITY;
        for (int j = is->body_start[k]; j < is->body_start[k + 1]; j++)
            rest = min_d(rest, f->st->bodies[is->bodies[j]].rest_s);
        if (rest < SLEEP_TIME)
            continue;
        for (int j = is->body_start[k]; j < is->body_start[k + 1]; j++) {
            sc_body *b = &f->st->bodies[is->bodies[j]];
            b->state = SC_ASLEEP;
            v3_set(b->v, 0, 0, 0);
            v3_set(b->w, 0, 0, 0);
        }
    }
}

