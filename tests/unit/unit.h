/* unit.h: shared declarations of the cmocka unit-test groups (one per module). */
#ifndef PM_UNIT_H
#define PM_UNIT_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

typedef struct {
    const char *name;
    const struct CMUnitTest *tests;
    size_t count;
} unit_group_t;

extern const unit_group_t unit_args, unit_common, unit_rng, unit_pmfile, unit_scene, unit_sampling;

/* A fresh temporary directory for the test run (created once). */
const char *unit_tmpdir(void);
/* Path of a file in the source tree (tests run from the repository root). */
#define UNIT_GROUP(var, label, arr) const unit_group_t var = {label, arr, sizeof arr / sizeof arr[0]}

#endif
