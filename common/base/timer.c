/* timer.c: clock_gettime wrappers (see timer.h). */
#include "base/timer.h"

#include <time.h>

static double now(clockid_t id)
{
    struct timespec ts;
    if (clock_gettime(id, &ts) != 0)
        return 0.0;
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double pm_time_wall(void) { return now(CLOCK_MONOTONIC); }
double pm_time_cpu(void) { return now(CLOCK_PROCESS_CPUTIME_ID); }
double pm_time_thread_cpu(void) { return now(CLOCK_THREAD_CPUTIME_ID); }

void pm_timer_start(pm_timer_t *t)
{
    t->wall0 = pm_time_wall();
    t->cpu0 = pm_time_cpu();
}

double pm_timer_wall(const pm_timer_t *t) { return pm_time_wall() - t->wall0; }
double pm_timer_cpu(const pm_timer_t *t) { return pm_time_cpu() - t->cpu0; }
