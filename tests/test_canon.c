/* test_canon.c - the canonical scenes with known answers (tests/canon.h)
 * and the structures (stacks of 10 to 40 boxes, two of them offset, a
 * pyramid of 15 rows and a wall: big islands, standing for STRUCT_T s):
 * every scene in both time-of-impact modes, on 1 and 2 workers, each
 * figure within its tolerance, and the same bits for either worker count;
 * the structures of 64 bodies and more again with their islands solved by
 * subdomains (SC_ISLAND_SUBDOMAINS, parts on the workers' threads).
 * bench/bench_canon prints the same figures beside ODE's. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "canon.h"

#define MAX_SCENES 64
#define STRUCT_T 2.0

static canon_scene scenes[MAX_SCENES];

/* The scene in time-of-impact modes [m0, m1) with island_method. */
static void meets_its_answer(const canon_scene *sc, int m0, int m1, int method)
{
    static const int modes[2] = { SC_TOI_LOCAL, SC_TOI_WORLD };
    for (int m = m0; m < m1; m++) {
        canon_traj t[2];
        for (int k = 0; k < 2; k++) {
            assert_int_equal(canon_traj_init(&t[k], sc), 0);
            assert_int_equal(canon_run_sc_method(sc, modes[m], k + 1, method, &t[k]), SC_OK);
        }
        size_t bytes = (size_t)(t[0].frames + 1) * (size_t)t[0].nd * 13 * sizeof *t[0].s;
        if (memcmp(t[0].s, t[1].s, bytes) != 0)
            fail_msg("%s, %s mode: 1 and 2 workers differ", sc->name, m ? "world" : "local");
        canon_fig f[CANON_MAX_FIGS];
        int nf = canon_judge(sc, &t[0], f);
        assert_true(nf > 0);
        for (int i = 0; i < nf; i++) {
            print_message("%-28s %-5s %-30s %12.6g (%s %.4g %s %.3g)\n", sc->name,
                          m ? "world" : "local", f[i].name, f[i].value,
                          f[i].how == CANON_AT_MOST ? "at most" : "expect", f[i].expect,
                          f[i].how == CANON_AT_MOST ? "+" : "+-", f[i].tol);
            if (!canon_pass(&f[i]))
                fail_msg("%s, %s mode: %s = %.6g, outside %.6g %s %.3g", sc->name,
                         m ? "world" : "local", f[i].name, f[i].value, f[i].expect,
                         f[i].how == CANON_AT_MOST ? "+" : "+-", f[i].tol);
        }
        canon_traj_free(&t[0]);
        canon_traj_free(&t[1]);
    }
}

static void scene_meets_its_known_answer(void **state)
{
    meets_its_answer(*state, 0, 2, sc_world_config_default().island_method);
}

static void structure_stands_by_subdomains(void **state)
{
    meets_its_answer(*state, 0, 1, SC_ISLAND_SUBDOMAINS);
}

int main(void)
{
    int n = canon_suite(scenes, MAX_SCENES);
    int s0 = n;
    n += canon_structures(scenes + n, MAX_SCENES - n, STRUCT_T);
    struct CMUnitTest tests[2 * MAX_SCENES];
    static char names[MAX_SCENES][64];
    int nt = 0;
    for (int i = 0; i < n; i++)
        tests[nt++] = (struct CMUnitTest){ scenes[i].name, scene_meets_its_known_answer, NULL,
                                           NULL, &scenes[i] };
    for (int i = s0; i < n; i++)
        if (scenes[i].nb >= 64) {
            snprintf(names[i], sizeof names[i], "%s by subdomains", scenes[i].name);
            tests[nt++] = (struct CMUnitTest){ names[i], structure_stands_by_subdomains, NULL, NULL,
                                               &scenes[i] };
        }
    return _cmocka_run_group_tests("test_canon", tests, (size_t)nt, NULL, NULL);
}
