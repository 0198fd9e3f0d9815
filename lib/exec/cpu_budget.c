/* cpu_budget.c - how many CPUs this process may use: its affinity mask,
 * and a cgroup CPU quota where one applies (docs/DESIGN.md 5.3).
 *
 * A thread that polls for work while idle burns what a quota allows and
 * takes the working threads' share of it, so that under a quota more
 * threads can run a frame slower than one. So idle threads poll only where
 * every thread that may poll has a CPU of its own. */
#include <errno.h>
#include <limits.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "exec.h"

#define CGROUP_ROOT "/sys/fs/cgroup"
#define TEXT_MAX 4096            /* /proc/self/cgroup and a quota file, at most */
#define DEPTH_MAX 64             /* ancestors looked at */

/* The first bytes of a file as a string; 0 when unreadable or empty. */
static size_t read_text(const char *path, char *buf, size_t cap)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return 0;
    size_t n = fread(buf, 1, cap - 1, f);
    fclose(f);
    buf[n] = '\0';
    return n;
}

/* A decimal integer at the start of s (after blanks); 0 when there is none. */
static int read_long(const char *s, const char **end, long long *v)
{
    while (*s == ' ' || *s == '\t')
        s++;
    char *e;
    errno = 0;
    *v = strtoll(s, &e, 10);
    if (e == s || errno)
        return 0;
    *end = e;
    return 1;
}

/* The quota in CPUs of one cgroup directory, or 0 for none: cgroup v2's
 * cpu.max ("max PERIOD" or "QUOTA PERIOD"), else v1's cpu.cfs_quota_us
 * (-1: none) over cpu.cfs_period_us. Malformed files count as none. */
static double dir_quota(const char *dir, int v2)
{
    char path[PATH_MAX], text[TEXT_MAX];
    long long q, p;
    const char *e;
    if (v2) {
        if (snprintf(path, sizeof path, "%s/cpu.max", dir) >= (int)sizeof path ||
            !read_text(path, text, sizeof text) || !strncmp(text, "max", 3) ||
            !read_long(text, &e, &q) || !read_long(e, &e, &p))
            return 0;
    } else {
        if (snprintf(path, sizeof path, "%s/cpu.cfs_quota_us", dir) >= (int)sizeof path ||
            !read_text(path, text, sizeof text) || !read_long(text, &e, &q))
            return 0;
        if (snprintf(path, sizeof path, "%s/cpu.cfs_period_us", dir) >= (int)sizeof path ||
            !read_text(path, text, sizeof text) || !read_long(text, &e, &p))
            return 0;
    }
    return q > 0 && p > 0 ? (double)q / (double)p : 0;
}

/* The smallest quota of dir and its ancestors down to root (dir inside
 * root); 0 for none. */
static double tree_quota(const char *root, const char *rel, int v2)
{
    char dir[PATH_MAX];
    if (snprintf(dir, sizeof dir, "%s%s%s", root, rel[0] == '/' ? "" : "/", rel) >=
        (int)sizeof dir)
        return 0;
    size_t rootlen = strlen(root);
    double least = 0;
    for (int depth = 0; depth < DEPTH_MAX; depth++) {
        double q = dir_quota(dir, v2);
        if (q > 0 && (least == 0 || q < least))
            least = q;
        char *slash = strrchr(dir, '/');
        if (!slash || (size_t)(slash - dir) < rootlen)
            break;
        *slash = '\0';
    }
    return least;
}

double sc_cpu_quota_at(const char *root, const char *proc_cgroup)
{
    if (!root || !proc_cgroup)
        return 0;
    double least = 0;
    /* lines "ID:CONTROLLERS:PATH": v2's is "0::PATH", v1's the one whose
     * controllers include cpu (mounted as cpu,cpuacct or cpu) */
    for (const char *line = proc_cgroup; *line;) {
        const char *nl = strchr(line, '\n');
        size_t len = nl ? (size_t)(nl - line) : strlen(line);
        char buf[TEXT_MAX];
        if (len < sizeof buf) {
            memcpy(buf, line, len);
            buf[len] = '\0';
            char *c1 = strchr(buf, ':');
            char *c2 = c1 ? strchr(c1 + 1, ':') : NULL;
            if (c2) {
                *c1 = '\0';
                *c2 = '\0';
                const char *ctrl = c1 + 1, *rel = c2 + 1;
                double q = 0;
                if (!strcmp(buf, "0") && !*ctrl) {
                    q = tree_quota(root, rel, 1);
                } else {
                    int cpu = 0;
                    char list[TEXT_MAX];
                    snprintf(list, sizeof list, "%s", ctrl);
                    char *save = NULL;
                    for (char *t = strtok_r(list, ",", &save); t; t = strtok_r(NULL, ",", &save))
                        cpu |= !strcmp(t, "cpu");
                    if (cpu) {
                        char mnt[PATH_MAX];
                        static const char *const names[] = { "cpu,cpuacct", "cpu" };
                        for (size_t i = 0; i < sizeof names / sizeof names[0] && q == 0; i++)
                            if (snprintf(mnt, sizeof mnt, "%s/%s", root, names[i]) <
                                (int)sizeof mnt)
                                q = tree_quota(mnt, rel, 0);
                    }
                }
                if (q > 0 && (least == 0 || q < least))
                    least = q;
            }
        }
        line += len + (nl != NULL);
    }
    return least;
}

SC_API double sc_cpu_budget(void)
{
    cpu_set_t set;
    long cpus = sched_getaffinity(0, sizeof set, &set) == 0 ? CPU_COUNT(&set)
                                                            : sysconf(_SC_NPROCESSORS_ONLN);
    double budget = cpus < 1 ? 1 : (double)cpus;
    char text[TEXT_MAX];
    if (read_text("/proc/self/cgroup", text, sizeof text)) {
        double q = sc_cpu_quota_at(CGROUP_ROOT, text);
        if (q > 0 && q < budget)
            budget = q;
    }
    return budget;
}
