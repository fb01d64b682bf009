/* progress.c: the terminal progress line (see progress.h). */
#include "base/progress.h"

#include <stdio.h>
#include <unistd.h>

#include "base/timer.h"

void pm_progress_begin(pm_progress_t *p, const char *label, uint64_t total, int enabled)
{
    p->label = label;
    p->total = total;
    atomic_store(&p->done, 0);
    atomic_store(&p->drawing, 0);
    p->t0 = pm_time_wall();
    atomic_store(&p->next, (int64_t)(1e6 * (p->t0 + 0.1)));
    p->enabled = enabled && isatty(2);
}

static void draw(pm_progress_t *p, uint64_t done, double now)
{
    double pct = p->total ? 100.0 * (double)done / (double)p->total : 100.0;
    fprintf(stderr, "\r%s: %5.1f%% (%llu of %llu) %.1f s", p->label, pct, (unsigned long long)done,
            (unsigned long long)p->total, now - p->t0);
    fflush(stderr);
}

void pm_progress_add(pm_progress_t *p, uint64_t n)
{
    uint64_t done = atomic_fetch_add(&p->done, n) + n;
    if (!p->enabled)
        return;
    double now = pm_time_wall();
    if ((int64_t)(1e6 * now) < atomic_load(&p->next))
        return;
    int expected = 0;
    if (!atomic_compare_exchange_strong(&p->drawing, &expected, 1))
        return;
    atomic_store(&p->next, (int64_t)(1e6 * (now + 0.1)));
    draw(p, done, now);
    atomic_store(&p->drawing, 0);
}

void pm_progress_end(pm_progress_t *p)
{
    if (!p->enabled)
        return;
    draw(p, atomic_load(&p->done), pm_time_wall());
    fputc('\n', stderr);
}
