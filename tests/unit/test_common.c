/* test_common.c: ISA detection and parsing, error messages, thread counts, hashing. */
#include <stdio.h>
#include <string.h>

#include "base/cpu.h"
#include "base/error.h"
#include "base/hash.h"
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
    assert_int_equal(pm_result_exit_code(PM_ERR_IO), 1);
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
                pm_error_slot_record(&slot, (uint64_t)t, pm_error_set(t < 20 ? PM_ERR_IO : PM_ERR_INPUT, "task %d failed", t));
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

static void test_common_threads_and_hash(void **state)
{
    assert_int_equal(pm_threads_use(3), 3);
    assert_int_equal(pm_threads_use(0), pm_threads_available());
    /* XXH3-64 of the empty input, as the xxHash specification gives it */
    assert_true(pm_hash_bytes("", 0) == 0x2D06800538D394C2ULL);
    uint64_t h;
    assert_int_equal(pm_hash_file("/nonexistent", &h), PM_ERR_IO);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_common_isa),
    cmocka_unit_test(test_common_errors),
    cmocka_unit_test(test_common_error_slot),
    cmocka_unit_test(test_common_threads_and_hash),
};
UNIT_GROUP(unit_common, "common", tests);
