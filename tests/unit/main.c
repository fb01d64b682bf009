/* main.c: the unit-test runner. `unit-tests [PATTERN]` runs every group or, with a pattern,
 * the groups whose name contains it (`kdtree`) and the tests whose name contains it or matches
 * it with * and ? wildcards (`test_kd_*`), so that `tests/run PATTERN` can pass its pattern on.
 * The last line is "unit: N passed, N failed" (of the tests run) for tests/run to add up. */
#include <fnmatch.h>
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

static int selected(const char *pattern, const char *group, const char *test)
{
    return !pattern || strstr(group, pattern) || strstr(test, pattern) || fnmatch(pattern, test, 0) == 0;
}

int main(int argc, char **argv)
{
    qsort(groups, ngroups, sizeof groups[0], by_name);
    const char *pattern = argc > 1 ? argv[1] : NULL;
    size_t total = 0, failed = 0, all = 0;
    for (size_t g = 0; g < ngroups; g++) {
        struct CMUnitTest *run = malloc(groups[g]->count * sizeof *run);
        if (!run) {
            fprintf(stderr, "unit: out of memory\n");
            return 3;
        }
        size_t n = 0;
        for (size_t i = 0; i < groups[g]->count; i++)
            if (selected(pattern, groups[g]->name, groups[g]->tests[i].name))
                run[n++] = groups[g]->tests[i];
        if (n)
            failed += (size_t)_cmocka_run_group_tests(groups[g]->name, run, n, NULL, NULL);
        total += n;
        all += groups[g]->count;
        free(run);
    }
    if (pattern)
        printf("unit: '%s' selects %zu of %zu tests\n", pattern, total, all);
    printf("unit: %zu passed, %zu failed\n", total - failed, failed);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", unit_tmpdir());
    if (system(cmd) != 0)
        fprintf(stderr, "unit: could not remove %s\n", unit_tmpdir());
    return failed ? 1 : 0;
}
