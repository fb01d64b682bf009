/* progress.h: a progress line on stderr, only when stderr is a terminal.
 *
 * pm_progress_add is safe to call from many threads; at most one of them redraws,
 * at most ten times a second, so the hot loop pays one atomic add per call. */
#ifndef PM_PROGRESS_H
#define PM_PROGRESS_H

#include <stdatomic.h>
#include <stdint.h>

typedef struct {
    const char *label;
    uint64_t total;
    _Atomic uint64_t done;
    _Atomic int drawing;  /* 1 while a thread redraws */
    _Atomic int64_t next; /* us (wall) of the next redraw */
    double t0;            /* s (wall) at begin */
    int enabled;
} pm_progress_t;

/* enabled: the caller's wish (not --quiet); the bar shows only if stderr is a tty too. */
void pm_progress_begin(pm_progress_t *p, const char *label, uint64_t total, int enabled);
void pm_progress_add(pm_progress_t *p, uint64_t n);
void pm_progress_end(pm_progress_t *p);

#endif
