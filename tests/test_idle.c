/* test_idle.c - idle CPU fraction without our own use, and the owner-busy
 * flag with hysteresis (daemon/idle.c), on /proc texts written here and on the
 * real /proc of this machine. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "idle.h"
#include "core.h"

static int parse(const char *s, sc_cpu_times *t)
{
    return sc_cpu_parse_stat(s, strlen(s), t);
}

static void test_stat_line_is_parsed(void **state)
{
    (void)state;
    sc_cpu_times t;
    const char *stat = "cpu  100 5 50 800 20 1 2 3 7 0\n"
                       "cpu0 50 2 25 400 10 0 1 1 3 0\nintr 1234\n";
    assert_int_equal(parse(stat, &t), SC_OK);
    /* the first eight counters; guest (7) is inside user already */
    assert_true(t.total == 100 + 5 + 50 + 800 + 20 + 1 + 2 + 3);
    assert_true(t.idle == 800 + 20);
    /* old kernels: four counters */
    assert_int_equal(parse("cpu 1 2 3 4\n", &t), SC_OK);
    assert_true(t.total == 10 && t.idle == 4);
}

static void test_bad_stat_is_a_format_error(void **state)
{
    (void)state;
    sc_cpu_times t;
    assert_int_equal(parse("", &t), SC_EFORMAT);
    assert_int_equal(parse("cpu0 1 2 3 4\n", &t), SC_EFORMAT);      /* no aggregate */
    assert_int_equal(parse("cpu 1 2 3\n", &t), SC_EFORMAT);         /* too few */
    assert_int_equal(parse("cpu x y z w\n", &t), SC_EFORMAT);
    assert_int_equal(parse("cpu 99999999999999999999999 1 1 1\n", &t), SC_EFORMAT);
    assert_int_equal(parse("cpu 18446744073709551615 1 1 1\n", &t), SC_EFORMAT); /* sum */
    /* every prefix of a good text: never a crash, never a wrong total */
    const char *good = "cpu  100 5 50 800 20 1 2 3\n";
    for (size_t n = 0; n < strlen(good); n++) {
        int rc = sc_cpu_parse_stat(good, n, &t);
        assert_true(rc == SC_EFORMAT || rc == SC_OK);
    }
}

static void test_self_ticks_are_parsed(void **state)
{
    (void)state;
    uint64_t ticks;
    /* fields: pid (comm) state ppid pgrp session tty tpgid flags minflt
     * cminflt majflt cmajflt utime stime ... */
    const char *s = "42 (sim clusterd) R 1 42 42 0 -1 4194304 100 0 0 0 250 50 0 0 20 0\n";
    assert_int_equal(sc_cpu_parse_self(s, strlen(s), &ticks), SC_OK);
    assert_true(ticks == 300);
    /* a name holding ") " does not fool it */
    const char *t = "7 (a) b (c) S 1 7 7 0 -1 0 0 0 0 0 11 22 0\n";
    assert_int_equal(sc_cpu_parse_self(t, strlen(t), &ticks), SC_OK);
    assert_true(ticks == 33);
    const char *bad = "7 (x) S 1 2 3\n";
    assert_int_equal(sc_cpu_parse_self(bad, strlen(bad), &ticks), SC_EFORMAT);
    assert_int_equal(sc_cpu_parse_self("no parens", 9, &ticks), SC_EFORMAT);
}

static void test_own_use_counts_as_idle(void **state)
{
    (void)state;
    sc_cpu_times a = { 1000, 800 }, b = { 2000, 1300 };
    /* 1000 ticks passed, 500 idle: 0.5 idle; our 300 ticks were not the owner's */
    assert_true(sc_idle_fraction(&a, &b, 0) == 0.5);
    assert_true(sc_idle_fraction(&a, &b, 300) == 0.8);
    assert_true(sc_idle_fraction(&a, &b, 900) == 1.0);      /* clamped */
    assert_true(sc_idle_fraction(&a, &a, 0) == -1);         /* no time passed */
    assert_true(sc_idle_fraction(&b, &a, 0) == -1);         /* backwards */
}

static void test_busy_flag_has_hysteresis(void **state)
{
    (void)state;
    sc_busy b = { 0 };
    /* threshold 0.5 owner load, hysteresis 0.2 */
    assert_int_equal(sc_busy_update(&b, 0.7, 0.5, 0.2), 0);  /* load 0.3 */
    assert_int_equal(sc_busy_update(&b, 0.4, 0.5, 0.2), 1);  /* load 0.6: busy */
    assert_int_equal(sc_busy_update(&b, 0.6, 0.5, 0.2), 1);  /* 0.4: still busy */
    assert_int_equal(sc_busy_update(&b, -1, 0.5, 0.2), 1);   /* no sample */
    assert_int_equal(sc_busy_update(&b, 0.75, 0.5, 0.2), 0); /* 0.25 < 0.3: free */
    assert_int_equal(sc_busy_update(&b, 0.45, 0.5, 0.2), 1);
}

static int read_text(const char *path, char *buf, size_t cap, size_t *len)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return 0;
    *len = fread(buf, 1, cap, f);
    fclose(f);
    return *len > 0;
}

static void test_this_machines_proc_parses(void **state)
{
    (void)state;
    char buf[65536];
    size_t len;
    if (!read_text("/proc/stat", buf, sizeof buf, &len)) {
        print_message("no /proc/stat here: skipped\n");
        return;
    }
    sc_cpu_times t;
    assert_int_equal(sc_cpu_parse_stat(buf, len, &t), SC_OK);
    assert_true(t.total > 0 && t.idle <= t.total);
    uint64_t ticks;
    assert_true(read_text("/proc/self/stat", buf, sizeof buf, &len));
    assert_int_equal(sc_cpu_parse_self(buf, len, &ticks), SC_OK);
}

/* A daemon pinned to some CPUs counts only their lines. */
static void test_cpu_set_sums_its_cpus(void **state)
{
    (void)state;
    const char *t = "cpu  40 0 0 60 0 0 0 0 0 0\n"
                    "cpu0 10 0 0 10 0 0 0 0 0 0\n"
                    "cpu1 30 0 0 50 0 0 0 0 0 0\n"
                    "cpu12 1 2 3 4 5\n"
                    "intr 1 2 3\n";
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(1, &set);
    sc_cpu_times c;
    assert_int_equal(sc_cpu_parse_stat_cpus(t, strlen(t), &set, &c), SC_OK);
    assert_int_equal(c.total, 80);
    assert_int_equal(c.idle, 50);
    CPU_SET(12, &set);
    assert_int_equal(sc_cpu_parse_stat_cpus(t, strlen(t), &set, &c), SC_OK);
    assert_int_equal(c.total, 95);
    assert_int_equal(c.idle, 59);       /* idle + iowait */
    assert_int_equal(sc_cpu_parse_stat_cpus(t, strlen(t), NULL, &c), SC_OK);
    assert_int_equal(c.total, 100);     /* NULL: the aggregate line */
    CPU_ZERO(&set);
    CPU_SET(5, &set);                   /* no line for it */
    assert_int_equal(sc_cpu_parse_stat_cpus(t, strlen(t), &set, &c), SC_EFORMAT);
    const char *bad = "cpu0 10 0 0\n";  /* three counters */
    CPU_SET(0, &set);
    assert_int_equal(sc_cpu_parse_stat_cpus(bad, strlen(bad), &set, &c), SC_EFORMAT);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_stat_line_is_parsed),
        cmocka_unit_test(test_bad_stat_is_a_format_error),
        cmocka_unit_test(test_self_ticks_are_parsed),
        cmocka_unit_test(test_own_use_counts_as_idle),
        cmocka_unit_test(test_busy_flag_has_hysteresis),
        cmocka_unit_test(test_this_machines_proc_parses),
        cmocka_unit_test(test_cpu_set_sums_its_cpus),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
