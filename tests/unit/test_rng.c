/* test_rng.c: Philox4x32-10 against the published known-answer vectors (Random123's
 * kat_vectors), and the stream properties the stages rely on. */
#include <math.h>

#include "math/rng.h"
#include "unit.h"

static void test_rng_known_answers(void **state)
{
    static const uint32_t cases[3][10] = {
        {0, 0, 0, 0, 0, 0, 0x6627e8d5, 0xe169c58d, 0xbc57ac4c, 0x9b00dbd8},
        {0xffffffff, 0xffffffff, 0xffffffff, 0xffffffff, 0xffffffff, 0xffffffff, 0x408f276d, 0x41c83b0e, 0xa20bc7c6,
         0x6d5451fd},
        {0x243f6a88, 0x85a308d3, 0x13198a2e, 0x03707344, 0xa4093822, 0x299f31d0, 0xd16cfe09, 0x94fdcceb, 0x5001e420,
         0x24126ea1},
    };
    for (int i = 0; i < 3; i++) {
        uint32_t out[4];
        pm_philox4x32_10(cases[i], cases[i] + 4, out);
        for (int k = 0; k < 4; k++)
            assert_int_equal(out[k], cases[i][6 + k]);
    }
}

static void test_rng_streams(void **state)
{
    pm_rng_t a, b, c;
    pm_rng_init(&a, 42, 7);
    pm_rng_init(&b, 42, 7);
    pm_rng_init(&c, 42, 8);
    int same_ac = 0;
    for (int i = 0; i < 1000; i++) {
        uint32_t x = pm_rng_u32(&a), y = pm_rng_u32(&b), z = pm_rng_u32(&c);
        assert_int_equal(x, y); /* the same key and stream replay exactly */
        same_ac += x == z;
    }
    assert_true(same_ac < 3);
}

static void test_rng_float_range_and_mean(void **state)
{
    pm_rng_t r;
    pm_rng_init(&r, 1, 0);
    double sum = 0;
    const int n = 200000;
    for (int i = 0; i < n; i++) {
        float u = pm_rng_float(&r);
        assert_true(u >= 0.0f && u < 1.0f);
        double d = pm_rng_double(&r);
        assert_true(d >= 0.0 && d < 1.0);
        sum += u;
    }
    /* mean 1/2, standard error sqrt(1/12/n) = 6.5e-4: 5 sigma */
    assert_true(fabs(sum / n - 0.5) < 5 * sqrt(1.0 / 12.0 / n));
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_rng_known_answers),
    cmocka_unit_test(test_rng_streams),
    cmocka_unit_test(test_rng_float_range_and_mean),
};
UNIT_GROUP(unit_rng, "rng", tests);
