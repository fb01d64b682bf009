/* main.c: the unit-test runner. `unit [NAME-PATTERN]` runs every group, or only the
 * tests whose names match the pattern (cmocka's * and ? wildcards). The last line is
 * "unit: N passed, N failed" for tests/run to add up. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "unit.h"

const char *unit_tmpdir(void)
{
    static char dir[512];
    if (!dir[0]) {
        const char *tmp = getenv("TMPDIR");
        snprintf(dir, sizeof dir, "%s/pmtk-unit-XXXXXX", tmp && *tmp ? tmp : "/tmp");
        if (!mkdtemp(dir)) {
            perror("mkdtemp");
            exit(3);
        }
    }
    return dir;
}

enum { UNIT_MAX_GROUPS = 64 };
static const unit_group_t *groups[UNIT_MAX_GROUPS];
static size_t ngroups;

void unit_register(const unit_group_t *group)
{
    if (ngroups == UNIT_MAX_GROUPS) {
        fprintf(stderr, "unit: more than %d groups; raise UNIT_MAX_GROUPS\n", UNIT_MAX_GROUPS);
        exit(3);
    }
    groups[ngroups++] = group;
}

static int by_name(const void *a, const void *b)
{
    return strcmp((*(const unit_group_t *const *)a)->name, (*(const unit_group_t *const *)b)->name);
}

int main(int argc, char **argv)
{
    qsort(groups, ngroups, sizeof groups[0], by_name);
    if (argc > 1)
        cmocka_set_test_filter(argv[1]);
    size_t total = 0, failed = 0;
    for (size_t g = 0; g < ngroups; g++) {
        int f = _cmocka_run_group_tests(groups[g]->name, groups[g]->tests, groups[g]->count, NULL, NULL);
        failed += (size_t)f;
        total += groups[g]->count;
    }
    if (argc > 1) /* cmocka does not say how many the filter kept: no count to add up */
        printf("unit: filter '%s': %zu failed\n", argv[1], failed);
    else
        printf("unit: %zu passed, %zu failed\n", total - failed, failed);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", unit_tmpdir());
    if (system(cmd) != 0)
        fprintf(stderr, "unit: could not remove %s\n", unit_tmpdir());
    return failed ? 1 : 0;
}
