/* idle.c - idle CPU fraction excluding our own use, and the owner-busy
 * flag (see idle.h). */
#include <stdlib.h>
#include <string.h>

#include "idle.h"
#include "simcluster.h"

/* Read an unsigned decimal at *p (after spaces); 0 when there is none. */
static int read_u64(const char **p, const char *end, uint64_t *v)
{
    const char *s = *p;
    while (s < end && *s == ' ')
        s++;
    if (s >= end || *s < '0' || *s > '9')
        return 0;
    uint64_t x = 0;
    for (; s < end && *s >= '0' && *s <= '9'; s++) {
        if (x > (UINT64_MAX - 9) / 10)
            return 0;    /* overflow: not a counter */
        x = 10 * x + (uint64_t)(*s - '0');
    }
    *v = x;
    *p = s;
    return 1;
}

/* The counters of one "cpu" line (after its name): SC_OK or SC_EFORMAT. */
static int parse_line(const char *p, const char *eol, sc_cpu_times *t)
{
    uint64_t f[8] = { 0 }, sum = 0;
    int n = 0;
    while (n < 8 && read_u64(&p, eol, &f[n]))
        n++;
    if (n < 4)
        return SC_EFORMAT;
    for (int i = 0; i < n; i++) {
        if (sum > UINT64_MAX - f[i])
            return SC_EFORMAT;
        sum += f[i];
    }
    t->total = sum;
    t->idle = f[3] + (n > 4 ? f[4] : 0);
    return SC_OK;
}

int sc_cpu_parse_stat(const char *text, size_t len, sc_cpu_times *t)
{
    return sc_cpu_parse_stat_cpus(text, len, NULL, t);
}

int sc_cpu_parse_stat_cpus(const char *text, size_t len, const cpu_set_t *cpus, sc_cpu_times *t)
{
    if (!text || !t)
        return SC_EINVAL;
    const char *end = text + len;
    sc_cpu_times sum = { 0, 0 };
    int found = 0;
    for (const char *line = text; line < end;) {
        const char *nl = memchr(line, '\n', (size_t)(end - line));
        const char *eol = nl ? nl : end;
        if (!cpus && eol - line > 4 && !memcmp(line, "cpu ", 4))
            return parse_line(line + 4, eol, t);
        if (cpus && eol - line > 4 && !memcmp(line, "cpu", 3) && line[3] >= '0' &&
            line[3] <= '9') {
            const char *p = line + 3;
            uint64_t id;
            sc_cpu_times one;
            if (!read_u64(&p, eol, &id) || parse_line(p, eol, &one) != SC_OK)
                return SC_EFORMAT;
            if (id < CPU_SETSIZE && CPU_ISSET((int)id, cpus)) {
                if (sum.total > UINT64_MAX - one.total)
                    return SC_EFORMAT;
                sum.total += one.total;
                sum.idle += one.idle;
                found++;
            }
        }
        line = eol + 1;
    }
    if (!found)
        return SC_EFORMAT;
    *t = sum;
    return SC_OK;
}

int sc_cpu_parse_self(const char *text, size_t len, uint64_t *ticks)
{
    if (!text || !ticks)
        return SC_EINVAL;
    /* "pid (comm) state ppid ...": comm may hold ") ", so the last ')' */
    const char *end = text + len, *close = NULL;
    for (const char *s = text; s < end; s++)
        if (*s == ')')
            close = s;
    if (!close)
        return SC_EFORMAT;
    /* after comm: field 3 (state) ... utime is field 14, stime 15 */
    const char *p = close + 1;
    int field = 2;
    uint64_t utime = 0, stime = 0;
    while (p < end && field < 15) {
        while (p < end && *p == ' ')
            p++;
        if (p >= end)
            break;
        field++;
        if (field == 14 || field == 15) {
            uint64_t v;
            if (!read_u64(&p, end, &v))
                return SC_EFORMAT;
            if (field == 14)
                utime = v;
            else
                stime = v;
        } else {
            while (p < end && *p != ' ' && *p != '\n')
                p++;
        }
    }
    if (field < 15 || utime > UINT64_MAX - stime)
        return SC_EFORMAT;
    *ticks = utime + stime;
    return SC_OK;
}

double sc_idle_fraction(const sc_cpu_times *a, const sc_cpu_times *b, uint64_t self_ticks)
{
    if (!a || !b || b->total <= a->total || b->idle < a->idle)
        return -1;
    double dt = (double)(b->total - a->total);
    double f = ((double)(b->idle - a->idle) + (double)self_ticks) / dt;
    return f < 0 ? 0 : f > 1 ? 1 : f;
}

int sc_busy_update(sc_busy *b, double idle_fraction, double threshold, double hysteresis)
{
    if (!b)
        return 0;
    if (!(idle_fraction >= 0) || idle_fraction > 1)
        return b->busy;    /* no new sample */
    double load = 1 - idle_fraction;
    if (!b->busy && load > threshold)
        b->busy = 1;
    else if (b->busy && load < threshold - hysteresis)
        b->busy = 0;
    return b->busy;
}
