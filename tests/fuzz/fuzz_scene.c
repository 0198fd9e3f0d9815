/* fuzz_scene.c - libFuzzer target for the scene file reader: any bytes go
 * to sc_scene_parse; it must refuse them with a documented code and a
 * "NAME:LINE:COLUMN: what" message, or accept them, and then a small
 * scene must build into a world and step once without harm. Mesh files are
 * looked up under a folder that does not exist, so relative names fail as
 * a missing file would. Built by tests/fuzz/run.sh (libFuzzer) and, with
 * replay_main.c, into the replay binary make check runs on
 * tests/fuzz/corpus/scene/. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "simcluster.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char err[256];
    memset(err, 'x', sizeof err);
    sc_scene *s = sc_scene_parse((const char *)data, size, "f", "/nonexistent-fuzz-dir", err,
                                 sizeof err);
    if (!memchr(err, 0, sizeof err))
        abort();                      /* the message is always terminated */
    if (!s) {
        int rc = sc_last_error();
        if (rc != SC_EFORMAT && rc != SC_EINVAL && rc != SC_ETOOBIG && rc != SC_EIO &&
            rc != SC_ENOTCLOSED && rc != SC_EDEGENERATE && rc != SC_ENOMEM)
            abort();
        if (strncmp(err, "f:", 2) != 0)
            abort();
        return 0;
    }
    int n = sc_scene_body_count(s);
    if (n <= 0)
        abort();
    if (n <= 64) {
        sc_world_config c = sc_world_config_default();
        c.workers = 1;
        sc_scene_config(s, &c);
        sc_world *w = sc_world_create(&c);
        if (w) {
            if (sc_scene_build(s, w) != SC_OK || sc_world_body_count(w) != n)
                abort();
            sc_world_step(w, 0.01);   /* may fail (e.g. bodies deep inside each other) */
            sc_world_destroy(w);
        }
    }
    sc_scene_free(s);
    return 0;
}
