/* fuzz_load.c - libFuzzer target for the mesh file parser: any bytes go to
 * sc_mesh_parse (OBJ, ASCII STL or binary STL); what it accepts goes on to
 * sc_shape_mesh, which must refuse or build it without harm. Built with
 * clang -fsanitize=fuzzer,address,undefined by tests/fuzz/run.sh, and with
 * replay_main.c into a plain replay binary that make check runs on
 * tests/fuzz/corpus/load/. */
#include <stdint.h>
#include <stdlib.h>

#include "core.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    double *xyz;
    int *tri, nverts, ntris;
    int rc = sc_mesh_parse(data, size, &xyz, &nverts, &tri, &ntris);
    if (rc != SC_OK) {
        /* the documented codes only, and nothing left to free */
        if ((rc != SC_EFORMAT && rc != SC_ETOOBIG && rc != SC_ENOMEM) || xyz || tri)
            abort();
        return 0;
    }
    if (nverts <= 0 || ntris <= 0 || nverts > SC_MESH_MAX_VERTS || ntris > SC_MESH_MAX_TRIS)
        abort();
    for (int i = 0; i < 3 * ntris; i++)
        if (tri[i] < 0 || tri[i] >= nverts)
            abort();
    for (int i = 0; i < nverts; i++)
        if (!sc_finite3(&xyz[3 * i]))
            abort();
    sc_shape *s = sc_shape_mesh(xyz, nverts, tri, ntris);
    if (s) {
        sc_mass_props mp;
        if (sc_shape_mass_props(s, &mp) != SC_OK || !(mp.volume > 0))
            abort();
    }
    sc_shape_release(s);
    free(xyz);
    free(tri);
    return 0;
}
