/* defaults.c - the default values of the public definition structs (the
 * world's configuration, a body's description), each with the cookie
 * that the call taking it checks, so that a caller who skipped the default
 * is caught. */
#include <string.h>

#include "core.h"
#include "vecmath.h"

SC_API sc_world_config sc_world_config_default(void)
{
    sc_world_config c;
    memset(&c, 0, sizeof c);
    v3_set(c.gravity, 0, 0, -9.81);
    c.broadphase = SC_BROADPHASE_AUTO;
    c.contact_tol_m = 1e-3;
    c.island_split = SC_ISLAND_SPLIT_DEFAULT;
    c.toi_mode = SC_TOI_LOCAL;
    c.internal_cookie = SC_CONFIG_COOKIE;
    return c;
}

SC_API sc_body_desc sc_body_desc_default(void)
{
    sc_body_desc d;
    memset(&d, 0, sizeof d);
    d.mass = 1;
    d.quat[0] = 1;
    d.restitution = 0.5;
    d.friction = 0.5;
    d.density = 1000;
    d.internal_cookie = SC_BODY_COOKIE;
    return d;
}
