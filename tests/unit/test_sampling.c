/* test_sampling.c: the warps produce the distributions they claim. */
#include <math.h>

#include "math/rng.h"
#include "math/sampling.h"
#include "unit.h"

static void test_sampling_cosine_hemisphere(void **state)
{
    pm_rng_t r;
    pm_rng_init(&r, 3, 0);
    const int n = 200000;
    double sum_cos = 0, sum_cos2 = 0;
    for (int i = 0; i < n; i++) {
        pm_vec3_t d = pm_sample_cosine_hemisphere(pm_rng_float(&r), pm_rng_float(&r));
        assert_true(fabsf(pm_v3_length(d) - 1.0f) < 1e-5f);
        assert_true(d.z >= 0.0f);
        sum_cos += d.z;
        sum_cos2 += d.z * d.z;
    }
    /* pdf cos/pi: E[cos] = 2/3, E[cos^2] = 1/2 */
    assert_true(fabs(sum_cos / n - 2.0 / 3.0) < 3e-3);
    assert_true(fabs(sum_cos2 / n - 0.5) < 3e-3);
}

static void test_sampling_onb(void **state)
{
    pm_rng_t r;
    pm_rng_init(&r, 4, 0);
    for (int i = 0; i < 10000; i++) {
        pm_vec3_t n = pm_sample_sphere(pm_rng_float(&r), pm_rng_float(&r)), t, b;
        if (i == 0)
            n = pm_v3(0, 0, -1); /* the branch's edge */
        pm_onb(n, &t, &b);
        assert_true(fabsf(pm_v3_dot(n, t)) < 1e-5f && fabsf(pm_v3_dot(n, b)) < 1e-5f);
        assert_true(fabsf(pm_v3_dot(t, b)) < 1e-5f);
        assert_true(fabsf(pm_v3_length(t) - 1) < 1e-5f && fabsf(pm_v3_length(b) - 1) < 1e-5f);
    }
}

static void test_sampling_triangle(void **state)
{
    pm_rng_t r;
    pm_rng_init(&r, 5, 0);
    const int n = 100000;
    double m0 = 0, m1 = 0;
    for (int i = 0; i < n; i++) {
        float b0, b1;
        pm_sample_triangle(pm_rng_float(&r), pm_rng_float(&r), &b0, &b1);
        assert_true(b0 >= 0 && b1 >= 0 && b0 + b1 <= 1.0f + 1e-6f);
        m0 += b0, m1 += b1;
    }
    /* uniform by area: every barycentric has mean 1/3 */
    assert_true(fabs(m0 / n - 1.0 / 3.0) < 4e-3 && fabs(m1 / n - 1.0 / 3.0) < 4e-3);
}

static void test_sampling_stratify_half_open(void **state)
{
    float s1, s2;
    pm_stratify(3, 3, 4, 4, 0x1.fffffep-1f, 0x1.fffffep-1f, &s1, &s2);
    assert_true(s1 < 1.0f && s2 < 1.0f && s1 >= 0.75f);
    pm_stratify(0, 2, 4, 4, 0.0f, 0.5f, &s1, &s2);
    assert_true(s1 == 0.0f && s2 == 0.625f);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_sampling_cosine_hemisphere),
    cmocka_unit_test(test_sampling_onb),
    cmocka_unit_test(test_sampling_triangle),
    cmocka_unit_test(test_sampling_stratify_half_open),
};
UNIT_GROUP(unit_sampling, "sampling", tests);
