/* timer.h: wall-clock and process CPU time, in seconds, for stage stats. */
#ifndef PM_TIMER_H
#define PM_TIMER_H

typedef struct {
    double wall0; /* s, CLOCK_MONOTONIC at start */
    double cpu0;  /* s, CLOCK_PROCESS_CPUTIME_ID at start (all threads) */
} pm_timer_t;

double pm_time_wall(void);       /* s since an arbitrary epoch, monotonic */
double pm_time_cpu(void);        /* s of CPU used by the whole process */
double pm_time_thread_cpu(void); /* s of CPU used by the calling thread */
void pm_timer_start(pm_timer_t *t);
double pm_timer_wall(const pm_timer_t *t); /* s since start */
double pm_timer_cpu(const pm_timer_t *t);  /* CPU s since start */

#endif
