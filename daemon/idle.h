/* idle.h - how idle a workstation's CPUs are, not counting our own work
 * (the daemon's heartbeat, docs/DESIGN.md section 7.3), and the owner-busy flag with hysteresis.
 * Parsers take the text of /proc/stat and /proc/self/stat, so they are
 * tested without a kernel. */
#ifndef SC_IDLE_H
#define SC_IDLE_H

#include <sched.h>
#include <stddef.h>
#include <stdint.h>

/* The aggregate "cpu" line of /proc/stat, in clock ticks. */
typedef struct sc_cpu_times {
    uint64_t total;           /* user + nice + system + idle + iowait + irq +
                                 softirq + steal (guest is inside user) */
    uint64_t idle;            /* idle + iowait */
} sc_cpu_times;

/* Parse /proc/stat text: SC_OK or SC_EFORMAT (no well-formed "cpu " line
 * with at least four counters). */
int sc_cpu_parse_stat(const char *text, size_t len, sc_cpu_times *t);
/* The same summed over the "cpuN" lines of the CPUs in cpus (a daemon's
 * affinity mask: the CPUs it can take time from); NULL = the aggregate
 * line. SC_EFORMAT when a cpuN line is malformed or none is in the set. */
int sc_cpu_parse_stat_cpus(const char *text, size_t len, const cpu_set_t *cpus, sc_cpu_times *t);
/* This process's CPU ticks (utime + stime) from /proc/self/stat text:
 * SC_OK or SC_EFORMAT. The command name may hold spaces and parentheses. */
int sc_cpu_parse_self(const char *text, size_t len, uint64_t *ticks);
/* Idle fraction between two samples with our own ticks counted as idle:
 * (d idle + d self) / d total, clamped to [0, 1]; -1 when no time passed
 * or the counters went backwards. */
double sc_idle_fraction(const sc_cpu_times *before, const sc_cpu_times *after,
                        uint64_t self_ticks);

/* The owner-busy flag: set when the owner's load (1 - idle) rises above
 * threshold, cleared only when it falls below threshold - hysteresis. */
typedef struct sc_busy {
    int busy;
} sc_busy;
/* Update with a new idle fraction (ignored when < 0); returns the flag. */
int sc_busy_update(sc_busy *b, double idle_fraction, double threshold, double hysteresis);

#endif
