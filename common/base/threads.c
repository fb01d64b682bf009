/* threads.c: OpenMP thread-count plumbing (see threads.h). */
#include "base/threads.h"

#include <omp.h>

int pm_threads_available(void) { return omp_get_num_procs(); }

int pm_threads_use(int64_t requested)
{
    int n = requested > 0 ? (int)requested : pm_threads_available();
    if (n < 1)
        n = 1;
    omp_set_num_threads(n);
    return n;
}
