/* test_common.c: ISA detection and parsing, error messages and their classes at a stage's
 * end, thread counts, hashing. */
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "base/cpu.h"
#include "base/error.h"
#include "base/hash.h"
#include "base/stage.h"
#include "base/threads.h"
#include "unit.h"

static void test_common_isa(void **state)
{
    pm_isa_t best = pm_cpu_best_isa(), isa;
    assert_true(pm_cpu_supports(best) && pm_cpu_supports(PM_ISA_SCALAR));
    assert_int_equal(pm_isa_parse("auto", &isa), PM_OK);
    assert_int_equal(isa, best);
    assert_int_equal(pm_isa_parse("scalar", &isa), PM_OK);
    assert_int_equal(isa, PM_ISA_SCALAR);
    assert_int_equal(pm_isa_parse("neon", &isa), PM_ERR_USAGE);
    assert_non_null(strstr(pm_error_message(), "unknown isa 'neon'"));
    for (int i = 0; i < PM_ISA_COUNT; i++) {
        assert_int_equal(pm_isa_width((pm_isa_t)i), i == 0 ? 1 : 2 << i); /* 1, 4, 8, 16 */
        if (!pm_cpu_supports((pm_isa_t)i))
            assert_int_equal(pm_isa_parse(pm_isa_name((pm_isa_t)i), &isa), PM_ERR_USAGE);
    }
    assert_true(strlen(pm_cpu_model()) > 0);
}

static void test_common_errors(void **state)
{
    assert_int_equal(pm_error_set(PM_ERR_INPUT, "bad '%s'\nsecond line", "x"), PM_ERR_INPUT);
    assert_string_equal(pm_error_message(), "bad 'x' second line"); /* always one line */
    pm_error_prefix("stage %d", 3);
    assert_string_equal(pm_error_message(), "stage 3: bad 'x' second line");
    assert_string_equal(pm_result_string(PM_ERR_NOMEM), "nomem");
    assert_int_equal(pm_result_exit_code(PM_OK), 0);
    assert_int_equal(pm_result_exit_code(PM_ERR_USAGE), 2);
    /* exit status by class (docs/cli.md): 1 input, 2 usage, 3 the system, 4 a bug */
    assert_int_equal(pm_result_exit_code(PM_ERR_INPUT), 1);
    assert_int_equal(pm_result_exit_code(PM_ERR_IO), 3);
    assert_int_equal(pm_result_exit_code(PM_ERR_NOMEM), 3);
    assert_int_equal(pm_result_exit_code(PM_ERR_INTERNAL), 4);
    assert_int_equal(pm_result_exit_code(99), 4); /* a code no one defined is a bug too */
    /* a wrong path is the user's (no retry fixes it); a full disk or a busy system may pass */
    assert_int_equal(pm_result_of_errno(ENOENT), PM_ERR_INPUT);
    assert_int_equal(pm_result_of_errno(ENOTDIR), PM_ERR_INPUT);
    assert_int_equal(pm_result_of_errno(EACCES), PM_ERR_INPUT);
    assert_int_equal(pm_result_of_errno(EISDIR), PM_ERR_INPUT);
    assert_int_equal(pm_result_of_errno(EBADF), PM_ERR_INPUT);
    assert_int_equal(pm_result_of_errno(ENOSPC), PM_ERR_IO);
    assert_int_equal(pm_result_of_errno(EIO), PM_ERR_IO);
    assert_int_equal(pm_result_of_errno(EDQUOT), PM_ERR_IO);
    assert_int_equal(pm_result_of_errno(EFBIG), PM_ERR_IO);
    assert_int_equal(pm_result_of_errno(EMFILE), PM_ERR_IO);
    assert_int_equal(pm_result_of_errno(EAGAIN), PM_ERR_IO);
    assert_int_equal(pm_result_of_errno(ENOMEM), PM_ERR_NOMEM);
    char longer[3000];
    memset(longer, 'a', sizeof longer - 1);
    longer[sizeof longer - 1] = '\0';
    pm_error_set(PM_ERR_INPUT, "%s", longer);
    pm_error_prefix("%s", longer); /* both cut, never overflowing */
    assert_true(strlen(pm_error_message()) < 1024);
}

/* Errors raised on OpenMP workers reach the calling thread, the lowest task's message for
 * any thread count, and a region with no failure leaves the caller's message alone. */
static void test_common_error_slot(void **state)
{
    for (int threads = 1; threads <= 4; threads++) {
        pm_error_slot_t slot;
        pm_error_slot_init(&slot);
        pm_error_set(PM_ERR_INPUT, "the caller's own");
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1)
        for (int t = 0; t < 64; t++) {
            if (t % 7 == 5)
                pm_error_slot_record(&slot, (uint64_t)t,
                                     pm_error_set(t < 20 ? PM_ERR_IO : PM_ERR_INPUT, "task %d failed", t));
            else
                pm_error_slot_record(&slot, (uint64_t)t, PM_OK);
        }
        assert_int_equal(pm_error_slot_raise(&slot), PM_ERR_IO);
        assert_string_equal(pm_error_message(), "task 5 failed");
    }
    pm_error_slot_t none;
    pm_error_slot_init(&none);
    pm_error_set(PM_ERR_INPUT, "kept");
#pragma omp parallel num_threads(2)
    pm_error_slot_record(&none, 0, PM_OK);
    assert_int_equal(pm_error_slot_raise(&none), PM_OK);
    assert_string_equal(pm_error_message(), "kept");
}

/* Runs a do-nothing stage whose work returns `code` with a fixed message, stderr caught in a
 * file; extra is one more positional argument (a usage error: the stage takes none).
 * Returns the exit status; the stderr text and the parsed --stats go to the out-parameters. */
static int run_stage(pm_result_t code, const char *extra, char *err_out, size_t cap, json_t **stats_out)
{
    char stats[1024], errpath[1024];
    snprintf(stats, sizeof stats, "%s/stage-end.json", unit_tmpdir());
    snprintf(errpath, sizeof errpath, "%s/stage-end.err", unit_tmpdir());
    unlink(stats);
    pm_stage_t st;
    pm_stage_defaults(&st);
    const pm_option_t opts[] = {PM_STAGE_COMMON_OPTIONS(st), {0}};
    const pm_cli_t cli = {"unit-stage", "[options]", "a stage that only fails", opts, 0, 0, NULL};
    char *argv[] = {"unit-stage", "--stats", stats, (char *)extra, NULL};
    fflush(stderr);
    int saved = dup(2), fd = open(errpath, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    assert_true(saved >= 0 && fd >= 0);
    dup2(fd, 2);
    close(fd);
    int rc = pm_stage_begin(&st, &cli, extra ? 4 : 3, argv);
    if (rc < 0) {
        pm_stage_stat_int(&st, "counted", 7);
        rc = pm_stage_end(&st, code == PM_OK ? PM_OK : pm_error_set(code, "cannot frob 'thing': %d of %d", 3, 5));
    }
    fflush(stderr);
    dup2(saved, 2);
    close(saved);
    FILE *f = fopen(errpath, "r");
    assert_non_null(f);
    size_t n = fread(err_out, 1, cap - 1, f);
    err_out[n] = '\0';
    fclose(f);
    *stats_out = json_load_file(stats, 0, NULL);
    return rc;
}

/* Every class: the exit status, the one line ending in "(CLASS error)", and --stats written
 * on failure with error.class and error.message; a success has no error key. */
static void test_common_stage_end_classes(void **state)
{
    static const pm_result_t codes[] = {PM_ERR_USAGE, PM_ERR_INPUT, PM_ERR_IO, PM_ERR_NOMEM, PM_ERR_INTERNAL};
    char err[4096], want[256];
    json_t *js;
    for (size_t i = 0; i < sizeof codes / sizeof codes[0]; i++) {
        const char *cls = pm_result_string(codes[i]);
        static const int status[] = {2, 1, 3, 3, 4}; /* docs/cli.md's table, in codes[]'s order */
        assert_int_equal(run_stage(codes[i], NULL, err, sizeof err, &js), status[i]);
        snprintf(want, sizeof want, "unit-stage: cannot frob 'thing': 3 of 5 (%s error)\n", cls);
        assert_string_equal(err, want);
        assert_non_null(js);
        assert_string_equal(json_string_value(json_object_get(js, "stage")), "unit-stage");
        json_t *e = json_object_get(js, "error");
        assert_string_equal(json_string_value(json_object_get(e, "class")), cls);
        assert_string_equal(json_string_value(json_object_get(e, "message")), "cannot frob 'thing': 3 of 5");
        assert_int_equal(json_integer_value(json_object_get(js, "counted")), 7); /* counters set before it */
        json_decref(js);
    }
    /* a wrong number of arguments: usage, the hint, and the stats say so too */
    assert_int_equal(run_stage(PM_OK, "surplus", err, sizeof err, &js), 2);
    assert_string_equal(err, "unit-stage: expected 0 arguments, got 1 (usage error)\n"
                             "usage: unit-stage [options] (try --help)\n");
    assert_non_null(js);
    assert_string_equal(json_string_value(json_object_get(json_object_get(js, "error"), "class")), "usage");
    json_decref(js);
    /* success: nothing on stderr, no error key */
    assert_int_equal(run_stage(PM_OK, NULL, err, sizeof err, &js), 0);
    assert_string_equal(err, "");
    assert_non_null(js);
    assert_null(json_object_get(js, "error"));
    assert_int_equal(json_integer_value(json_object_get(js, "counted")), 7);
    json_decref(js);
}

static void test_common_threads_and_hash(void **state)
{
    assert_int_equal(pm_threads_use(3), 3);
    assert_int_equal(pm_threads_use(0), pm_threads_available());
    /* XXH3-64 of the empty input, as the xxHash specification gives it */
    assert_true(pm_hash_bytes("", 0) == 0x2D06800538D394C2ULL);
    uint64_t h;
    assert_int_equal(pm_hash_file("/nonexistent", &h), PM_ERR_INPUT); /* a wrong path: no retry fixes it */
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_common_isa),
    cmocka_unit_test(test_common_errors),
    cmocka_unit_test(test_common_error_slot),
    cmocka_unit_test(test_common_stage_end_classes),
    cmocka_unit_test(test_common_threads_and_hash),
};
UNIT_GROUP(unit_common, "common", tests);
