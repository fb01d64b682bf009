/* unit.h: shared declarations of the cmocka unit-test groups (one per module). */
#ifndef PM_UNIT_H
#define PM_UNIT_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

/* After the four above: cmocka.h uses them without including them. */
#include <cmocka.h>

typedef struct {
    const char *name;
    const struct CMUnitTest *tests;
    size_t count;
} unit_group_t;

/* Groups register themselves before main runs (UNIT_GROUP), so that a new test file needs
 * no edit anywhere else; main sorts them by name so that the order does not depend on the
 * link order. */
void unit_register(const unit_group_t *group);

/* A fresh temporary directory for the test run (created once). */
const char *unit_tmpdir(void);
/* Chi-square of observed counts obs against probabilities prob (nbins bins, n samples): bins
 * expecting fewer than 5 samples are pooled into one; fails at once on a sample in a bin expecting
 * none (below 1e-3). Its degrees of freedom in *dof (unit_stats.c). */
double unit_chi2_pooled(const char *name, const double *obs, const double *prob, int nbins, double n, int *dof);
/* Fails when chi2 exceeds the mean plus 5 standard deviations of a chi-square of dof degrees. */
void unit_check_chi2(const char *name, double chi2, int dof);

/* Path of a file in the source tree (tests run from the repository root). */
#define UNIT_GROUP(var, label, arr)                                                                                    \
    static const unit_group_t var = {label, arr, sizeof arr / sizeof arr[0]};                                          \
    __attribute__((constructor)) static void var##_register(void) { unit_register(&var); }

#endif
