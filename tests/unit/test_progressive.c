/* test_progressive.c: the anytime budget's pass sizes (common/engine/progressive.h,
 * pm_progressive_next_size) on made-up pass times, the pass plan a resident tracer reads
 * (common/base/passplan.h): ranges, plan lines, and bad ones named by line, and the radius
 * schedule by photons (common/photonmap/gather_stage.h). No timing: the times here are
 * numbers given to the functions. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/passplan.h"
#include "engine/progressive.h"
#include "photonmap/gather_stage.h"
#include "unit.h"

/* Passes of 1, 2, 4 units at exactly 0.1 + 0.2 k s: a pass of u units is bounded by the least
 * of sec_j max(1, u / k_j). */
static void test_sizes_grow_then_fill(void **state)
{
    (void)state;
    int k[8] = {1, 2, 4};
    double sec[8] = {0.3, 0.5, 0.9};
    /* plenty left: doubling up to kmax 16 */
    assert_int_equal(pm_progressive_next_size(k, sec, 3, 16, 100.0), 8);
    k[3] = 8, sec[3] = 1.7;
    assert_int_equal(pm_progressive_next_size(k, sec, 4, 16, 100.0), 16);
    k[4] = 16, sec[4] = 3.3;
    assert_int_equal(pm_progressive_next_size(k, sec, 5, 16, 100.0), 16); /* kmax caps the growth */
    /* 7 s left: 16 units (3.3 s) and the 16 after them fit */
    assert_int_equal(pm_progressive_next_size(k, sec, 5, 16, 7.0), 16);
    /* 3.75 s left: after 16 units no pass of 16 would fit: the last pass ends by the budget
     * with 5% to spare and is no larger than a full pass, 16 units (17 would fit, 3.3 x 17 /
     * 16 x 1.05 = 3.68 s, but a pass above kmax costs more than its share) */
    assert_int_equal(pm_progressive_next_size(k, sec, 5, 16, 3.75), 16);
    /* what is left after it goes to a smaller pass: 0.45 s, 1 unit (0.3 s x 1.05) */
    assert_int_equal(pm_progressive_next_size(k, sec, 5, 16, 0.45), 1);
    /* 2.1 s left: the last pass shrinks to what ends there: 9 units, bounded by pass 4's 1.7 s
     * times 9 / 8 = 1.91 s (x 1.05: 2.01 s; 10 units: 2.23 s) */
    assert_int_equal(pm_progressive_next_size(k, sec, 5, 16, 2.1), 9);
    /* less than one unit left: stop */
    assert_int_equal(pm_progressive_next_size(k, sec, 5, 16, 0.25), 0);
}

/* A pass that comes with a new coverage level's sampling: that time set aside, or the samples
 * kept (hold) when it does not fit or would take half the pass. */
static void test_sizes_cover_hold(void **state)
{
    (void)state;
    int k[8] = {1, 2, 4, 8, 16};
    double sec[8] = {0.1, 0.2, 0.4, 0.8, 1.6};
    static const struct {
        double remaining, extra;
        int holdable, units, hold;
    } cases[] = {
        {100.0, 1.0, 1, 16, 0}, /* plenty left: the level is paid, the pass grows as ever */
        /* 1.2 s left, the level foreseen at 1.3 s: it does not fit; kept, the pass takes 1.2 s
         * (11 units: 1.1 s x 1.05 = 1.155 s) */
        {1.2, 1.3, 1, 11, 1},
        {1.2, 1.3, 0, 0, 0},  /* the same level two finer (not holdable): the render ends */
        {1.2, 0.8, 1, 11, 1}, /* the level at 0.8 s: 3 units with it (0.4 s) against 11 without: kept */
        {1.2, 0.3, 1, 8, 0},  /* the level at 0.3 s: 8 units with it (0.84 s) against 11: paid */
        {1.2, 0.0, 1, 11, 0}, /* no sampling foreseen: the plain size */
        {0.05, 1.0, 1, 0, 0}, /* not even a unit left: nothing to keep either */
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        int hold = -1;
        assert_int_equal(
            pm_progressive_cover_size(k, sec, 5, 16, cases[i].remaining, cases[i].extra, cases[i].holdable, &hold),
            cases[i].units);
        assert_int_equal(hold, cases[i].hold);
    }
}

/* The caustic gather's levels are not foreseen: the passes the budget cuts short keep its
 * samples; the growing passes and the full ones do not. */
static void test_sizes_hold_caustic(void **state)
{
    (void)state;
    int k[8] = {1, 2, 4, 8, 16, 16};
    assert_int_equal(pm_progressive_hold_caustic(k, 0, 16, 1), 0);  /* pass 1: nothing to keep */
    assert_int_equal(pm_progressive_hold_caustic(k, 1, 16, 2), 0);  /* growing */
    assert_int_equal(pm_progressive_hold_caustic(k, 4, 16, 16), 0); /* growing to a full pass */
    assert_int_equal(pm_progressive_hold_caustic(k, 5, 16, 16), 0); /* full */
    assert_int_equal(pm_progressive_hold_caustic(k, 6, 16, 14), 1); /* cut short */
    assert_int_equal(pm_progressive_hold_caustic(k, 6, 16, 1), 1);
    assert_int_equal(pm_progressive_hold_caustic(k, 3, 16, 3), 1); /* a 1-s budget's last: 1, 2, 4, then 3 */
    assert_int_equal(pm_progressive_hold_caustic(k, 3, 16, 0), 0); /* no pass */
}

static void test_sizes_first_pass(void **state)
{
    (void)state;
    /* no pass yet: one unit */
    assert_int_equal(pm_progressive_next_size(NULL, NULL, 0, 16, 10.0), 1);
    /* one pass of 1 unit in 0.4 s, the rate alone (c = 0): 2 units fit in 10 s, and the 4
     * after them */
    int k[2] = {1};
    double sec[2] = {0.4};
    assert_int_equal(pm_progressive_next_size(k, sec, 1, 16, 10.0), 2);
    /* 0.9 s left: no room for 2 and then 4 units; the last pass: 2 units would end by it at
     * 0.8 x 1.05 s, but twice the largest pass so far takes 10% more margin (0.8 x 1.15 =
     * 0.92 s): 1 unit; 1 s left: 2 units */
    assert_int_equal(pm_progressive_next_size(k, sec, 1, 16, 0.9), 1);
    assert_int_equal(pm_progressive_next_size(k, sec, 1, 16, 1.0), 2);
    assert_int_equal(pm_progressive_next_size(k, sec, 1, 16, 0.3), 0);
    /* the first pass pays the stages' start: it loosens no bound the later passes give */
    int k3[4] = {1, 2, 4};
    double s3[4] = {2.0, 0.5, 0.9};
    assert_int_equal(pm_progressive_next_size(k3, s3, 3, 16, 5.5), 8); /* 1.8 + 3.6 <= 5.5 */
    /* the last pass, beyond the largest so far (4 units): 0.9 x u / 4 s, times 1.05 plus 0.1 for
     * each multiple of 4 units beyond the first, at most 1.25: 14 units (3.15 x 1.25 = 3.94 s;
     * 15: 4.22 s) in 4.2 s, 10 (2.25 x 1.2 = 2.7 s; 11: 2.475 x 1.225 = 3.03 s) in 3 s */
    assert_int_equal(pm_progressive_next_size(k3, s3, 3, 16, 4.2), 14);
    assert_int_equal(pm_progressive_next_size(k3, s3, 3, 16, 3.0), 10);
    /* no larger than the largest so far: 1.05 alone (16 units in 0.9 x 4 x 1.05 = 3.78 s) */
    int k4[5] = {1, 2, 4, 16};
    double s4[5] = {2.0, 0.5, 0.9, 3.6};
    assert_int_equal(pm_progressive_next_size(k4, s4, 4, 16, 3.8), 16);
}

static void test_sizes_noisy(void **state)
{
    (void)state;
    /* a larger pass that took less time (other work on the machine): the tightest bound,
     * 5 units by pass 3's 0.8 x 5 / 4 = 1.0 s (x 1.075, a quarter beyond the largest pass:
     * 1.075 s), so in 1.06 s 4 units, in 1.08 s 5 */
    int k[3] = {1, 2, 4};
    double sec[3] = {0.3, 0.9, 0.8};
    assert_int_equal(pm_progressive_next_size(k, sec, 3, 16, 1.06), 4);
    assert_int_equal(pm_progressive_next_size(k, sec, 3, 16, 1.08), 5);
    /* the measured case this rule replaced a line fit for: 1 unit in 1.753 s (the stages'
     * start included), 3 units in 1.867 s, 3.96 s left: 5 units (bounded by 3.11 s, x 1.117:
     * 3.47 s; 6 units 3.73 x 1.15 = 4.29 s), not 41 */
    int km[2] = {1, 3};
    double sm[2] = {1.753, 1.867};
    assert_int_equal(pm_progressive_next_size(km, sm, 2, 16, 3.96), 5);
}

static void test_plan_range(void **state)
{
    (void)state;
    pm_passplan_t pp;
    int64_t pass, size;
    int end;
    assert_int_equal(pm_passplan_open(&pp, "3:4", NULL), PM_OK);
    assert_false(pm_passplan_single(&pp));
    assert_int_equal(pm_passplan_next(&pp, &pass, &size, &end), PM_OK);
    assert_true(pass == 3 && size == 0 && !end);
    assert_int_equal(pm_passplan_next(&pp, &pass, &size, &end), PM_OK);
    assert_true(pass == 4 && !end);
    assert_int_equal(pm_passplan_next(&pp, &pass, &size, &end), PM_OK);
    assert_true(end);
    pm_passplan_close(&pp);
    assert_int_equal(pm_passplan_open(&pp, "2:2", NULL), PM_OK);
    assert_true(pm_passplan_single(&pp));
    const char *bad[] = {"0:2", "3:2", "2", ":4", "1:x", "a:b"};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++)
        assert_int_equal(pm_passplan_open(&pp, bad[i], NULL), PM_ERR_USAGE);
    assert_int_equal(pm_passplan_open(&pp, NULL, NULL), PM_ERR_USAGE);
    assert_int_equal(pm_passplan_open(&pp, "1:2", "plan"), PM_ERR_USAGE);
}

static void test_plan_lines(void **state)
{
    (void)state;
    char path[4096];
    snprintf(path, sizeof path, "%s/plan.txt", unit_tmpdir());
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs("# passes\n1 18750\n\n2\n 5\t300000 \nx 3\n", f);
    fclose(f);
    pm_passplan_t pp;
    int64_t pass, size;
    int end;
    assert_int_equal(pm_passplan_open(&pp, NULL, path), PM_OK);
    assert_int_equal(pm_passplan_next(&pp, &pass, &size, &end), PM_OK);
    assert_true(pass == 1 && size == 18750 && !end);
    assert_int_equal(pm_passplan_next(&pp, &pass, &size, &end), PM_OK);
    assert_true(pass == 2 && size == 0);
    assert_int_equal(pm_passplan_next(&pp, &pass, &size, &end), PM_OK);
    assert_true(pass == 5 && size == 300000);
    assert_int_equal(pm_passplan_next(&pp, &pass, &size, &end), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "line 6"));
    pm_passplan_close(&pp);
    const char *bad[] = {"0\n", "1 0\n", "1 2 3\n", "-1\n", "1 2x\n"};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        f = fopen(path, "w");
        fputs(bad[i], f);
        fclose(f);
        assert_int_equal(pm_passplan_open(&pp, NULL, path), PM_OK);
        assert_int_equal(pm_passplan_next(&pp, &pass, &size, &end), PM_ERR_INPUT);
        pm_passplan_close(&pp);
    }
    /* an empty plan ends at once */
    f = fopen(path, "w");
    fclose(f);
    assert_int_equal(pm_passplan_open(&pp, NULL, path), PM_OK);
    assert_int_equal(pm_passplan_next(&pp, &pass, &size, &end), PM_OK);
    assert_true(end);
    pm_passplan_close(&pp);
    snprintf(path, sizeof path, "%s/no-such-plan", unit_tmpdir());
    assert_int_equal(pm_passplan_open(&pp, NULL, path), PM_ERR_INPUT);
}

/* pm_passplan_run: each pass's command is that pass's alone (--plan out, --pass P in, and the
 * size option when the plan sizes it), restored after; a size above the limit names the line;
 * a failing pass is named; an empty plan is an input error. */
typedef struct {
    pm_stage_t *st;
    int calls;
    char cmd[4][256];
    int fail_at; /* the pass that fails, 0: none */
} run_log_t;

static pm_result_t log_pass(void *user, int64_t pass, int64_t size)
{
    (void)size;
    run_log_t *l = user;
    char *c = l->cmd[l->calls++ & 3];
    c[0] = '\0';
    for (int i = 0; i < l->st->argc; i++)
        snprintf(c + strlen(c), 256 - strlen(c), "%s%s", i ? " " : "", l->st->argv[i]);
    return pass == l->fail_at ? pm_error_set(PM_ERR_INPUT, "bad pass") : PM_OK;
}

static void test_plan_run(void **state)
{
    (void)state;
    char path[4096];
    snprintf(path, sizeof path, "%s/plan-run.txt", unit_tmpdir());
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs("1 50\n2\n", f);
    fclose(f);
    pm_stage_t st;
    pm_stage_defaults(&st);
    const char *plan = NULL;
    int64_t photons = 10;
    const pm_option_t opts[] = {PM_STAGE_COMMON_OPTIONS(st),
                                {"plan", 0, PM_OPT_STRING, &plan, "FILE", "plan", 1, 0, NULL},
                                {"photons", 0, PM_OPT_INT, &photons, "N", "photons", 1, 1e12, NULL},
                                {0}};
    const pm_cli_t cli = {"unit-tracer", "[options]", "a tracer of passes", opts, 0, 0, NULL};
    char *argv[] = {"unit-tracer", "--photons", "10", "--plan", path, "-q", NULL};
    assert_int_equal(pm_stage_begin(&st, &cli, 6, argv), -1);
    const void *drop[] = {&plan, &photons};
    run_log_t l = {.st = &st};
    char **argv0 = st.argv;
    int argc0 = st.argc;
    pm_passplan_t pp;
    assert_int_equal(pm_passplan_open(&pp, NULL, path), PM_OK);
    assert_int_equal(pm_passplan_run(&pp, &st, argv, drop, 2, "--photons", 100, log_pass, &l), PM_OK);
    pm_passplan_close(&pp);
    assert_int_equal(l.calls, 2);
    assert_non_null(strstr(l.cmd[0], "--pass 1 --photons 50"));
    assert_null(strstr(l.cmd[0], "--plan"));
    assert_non_null(strstr(l.cmd[1], "--photons 10"));
    assert_non_null(strstr(l.cmd[1], "--pass 2"));
    assert_true(st.argv == argv0 && st.argc == argc0); /* restored */
    /* a size above the limit, named by its line */
    f = fopen(path, "w");
    fputs("1\n2 500\n", f);
    fclose(f);
    l.calls = 0;
    assert_int_equal(pm_passplan_open(&pp, NULL, path), PM_OK);
    assert_int_equal(pm_passplan_run(&pp, &st, argv, drop, 2, "--photons", 100, log_pass, &l), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "line 2"));
    pm_passplan_close(&pp);
    /* a failing pass is named */
    l.calls = 0, l.fail_at = 1;
    assert_int_equal(pm_passplan_open(&pp, "1:3", NULL), PM_OK);
    assert_int_not_equal(pm_passplan_run(&pp, &st, argv, drop, 2, "--photons", 100, log_pass, &l), PM_OK);
    assert_non_null(strstr(pm_error_message(), "pass 1"));
    assert_int_equal(l.calls, 1);
    pm_passplan_close(&pp);
    /* an empty plan names no pass */
    f = fopen(path, "w");
    fclose(f);
    l.fail_at = 0;
    assert_int_equal(pm_passplan_open(&pp, NULL, path), PM_OK);
    assert_int_equal(pm_passplan_run(&pp, &st, argv, drop, 2, "--photons", 100, log_pass, &l), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "names no pass"));
    pm_passplan_close(&pp);
    pm_args_free(&st.args);
}

/* --ready: the line is in the file before the first pass runs (the driver times pass 1 from
 * it), once, naming the program; a file that cannot be opened is an error naming it. */
static pm_result_t ready_seen(void *user, int64_t pass, int64_t size)
{
    (void)pass, (void)size;
    const char *path = user;
    char line[256] = "";
    FILE *f = fopen(path, "r");
    if (!f || !fgets(line, sizeof line, f) || strncmp(line, "unit-tracer ready ", 18)) {
        if (f)
            fclose(f);
        return pm_error_set(PM_ERR_INTERNAL, "no ready line before the pass: '%s'", line);
    }
    fclose(f);
    return PM_OK;
}

static void test_plan_ready(void **state)
{
    (void)state;
    char ready[4096], bad[4096];
    snprintf(ready, sizeof ready, "%s/plan-ready.txt", unit_tmpdir());
    snprintf(bad, sizeof bad, "%s/no-such-dir/ready", unit_tmpdir());
    remove(ready);
    pm_stage_t st;
    pm_stage_defaults(&st);
    const pm_option_t opts[] = {PM_STAGE_COMMON_OPTIONS(st), {0}};
    const pm_cli_t cli = {"unit-tracer", "[options]", "a tracer of passes", opts, 0, 0, NULL};
    char *argv[] = {"unit-tracer", "-q", NULL};
    assert_int_equal(pm_stage_begin(&st, &cli, 2, argv), -1);
    const void *drop[] = {&st.seed};
    pm_passplan_t pp;
    assert_int_equal(pm_passplan_open(&pp, "1:2", NULL), PM_OK);
    pp.ready = ready;
    assert_int_equal(pm_passplan_run(&pp, &st, argv, drop, 1, "--photons", 100, ready_seen, ready), PM_OK);
    pm_passplan_close(&pp);
    char line[256] = "", name[64] = "";
    double w = -1.0, c = -1.0;
    FILE *f = fopen(ready, "r");
    assert_non_null(f);
    assert_non_null(fgets(line, sizeof line, f));
    assert_null(fgets(line + 128, 128, f)); /* one line */
    fclose(f);
    assert_int_equal(sscanf(line, "%63s ready %lf %lf", name, &w, &c), 3);
    assert_string_equal(name, "unit-tracer");
    assert_true(w >= 0.0 && c >= 0.0);
    assert_int_equal(pm_passplan_open(&pp, "1:1", NULL), PM_OK);
    pp.ready = bad;
    assert_int_equal(pm_passplan_run(&pp, &st, argv, drop, 1, "--photons", 100, ready_seen, ready), PM_ERR_INPUT);
    assert_non_null(strstr(pm_error_message(), "no-such-dir/ready"));
    pm_passplan_close(&pp);
    pm_args_free(&st.args);
}

/* The schedule by photons: passes of pass 1's size sit at their own index, to the bit (the
 * fixed-size renders keep their bytes); between them the continuous form is monotone and
 * meets the product at both ends; small passes move the index by their photons alone. */
static void test_schedule_by_photons(void **state)
{
    (void)state;
    const double a = 2.0 / 3.0, r1 = 0.25;
    for (uint64_t p = 1; p <= 300; p++) {
        double n = pm_gather_pass_index(p, (p - 1) * 18750, 18750);
        assert_true(n == (double)p);
        assert_true(pm_gather_schedule_radius(r1, n, a) == pm_gather_pass_radius(r1, p, a));
    }
    assert_true(pm_gather_pass_index(7, 123, 0) == 7.0); /* no photon counts: the pass itself */
    /* the continuous form at an integer, off the product's exact path, agrees to rounding */
    for (uint64_t p = 2; p <= 1000; p *= 3) {
        double lg = r1 * sqrt(exp(lgamma((double)p + a) - lgamma(1.0 + a) - lgamma((double)p + 1.0)));
        assert_true(fabs(lg / pm_gather_pass_radius(r1, p, a) - 1.0) < 1e-12);
    }
    /* monotone between the integers, and continuous at them */
    double last = r1;
    for (double n = 1.0; n <= 20.0; n += 0.125) {
        double r = pm_gather_schedule_radius(r1, n, a);
        assert_true(r <= last);
        last = r;
    }
    double below = pm_gather_schedule_radius(r1, 5.0 - 1e-9, a), at = pm_gather_schedule_radius(r1, 5.0, a);
    assert_true(fabs(below / at - 1.0) < 1e-8);
    /* 16 passes of 1/16 of pass 1's photons move the index by 1, not by 16 */
    assert_true(pm_gather_pass_index(17, 16 * 1000, 16000) == 2.0);
    /* the options: both counts or neither, only with a pass, none before pass 1 */
    assert_int_equal(pm_gather_pass_check(0, -1, 0), PM_OK);
    assert_int_equal(pm_gather_pass_check(3, 200, 100), PM_OK);
    assert_int_equal(pm_gather_pass_check(1, 0, 100), PM_OK);
    assert_int_equal(pm_gather_pass_check(1, -1, 100), PM_OK);
    assert_int_equal(pm_gather_pass_check(0, 5, 100), PM_ERR_USAGE);
    assert_int_equal(pm_gather_pass_check(3, 200, 0), PM_ERR_USAGE);
    assert_int_equal(pm_gather_pass_check(3, -1, 100), PM_ERR_USAGE);
    assert_int_equal(pm_gather_pass_check(1, 100, 100), PM_ERR_USAGE);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_sizes_grow_then_fill), cmocka_unit_test(test_sizes_first_pass),
    cmocka_unit_test(test_sizes_cover_hold),     cmocka_unit_test(test_sizes_hold_caustic),
    cmocka_unit_test(test_sizes_noisy),          cmocka_unit_test(test_plan_range),
    cmocka_unit_test(test_plan_lines),           cmocka_unit_test(test_plan_run),
    cmocka_unit_test(test_plan_ready),           cmocka_unit_test(test_schedule_by_photons),
};
UNIT_GROUP(progressive_group, "progressive", tests)
