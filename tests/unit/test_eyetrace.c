/* test_eyetrace.c: the eye tracer of common/render/eyetrace.h through its API, on the closed
 * box of tests/scenes (8 x 8 pixels, no ray escapes): the sink gets every query in pixel
 * order and every row of direct light once, the same bytes for any thread count and
 * schedule; a sink's failure stops the trace with its message; a bad spp is refused. Images
 * of 80 and 65 rows (three bands of up to 32: one band's records go to the sink on a worker
 * while the next is traced) check the same across bands, and a failure in the first or the
 * second band's records. */
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "base/cpu.h"
#include "base/error.h"
#include "formats/formats.h"
#include "render/eyetrace.h"
#include "render/rt.h"
#include "render/scene.h"
#include "unit.h"

#define CLOSED_BOX "tests/scenes/closed-box/scene.json"
#define MAX_ROWS 80 /* the tallest image traced here: three bands */

typedef struct {
    unsigned char *q; /* every query record received */
    size_t qn, qcap;
    double direct[8 * MAX_ROWS * 3];
    int rows_seen[MAX_ROWS];
    uint32_t record_size, off_pixel, last_pixel;
    int out_of_order, fail_after; /* fail_after: records after which the queries sink fails once, 0 for never */
    pthread_t caller;             /* the thread that called pm_eye_trace */
    int off_caller, failed_off;   /* sink calls made on another thread; 1 when the failure was one */
} sink_t;

static pm_result_t got_queries(void *user, const void *records, uint64_t count)
{
    sink_t *k = user;
    int off = !pthread_equal(pthread_self(), k->caller);
    k->off_caller += off;
    if (k->fail_after && k->qn / k->record_size + count > (size_t)k->fail_after) {
        k->fail_after = 0; /* once: a call after it would succeed, so a failure the trace lost shows */
        k->failed_off = off;
        return pm_error_set(PM_ERR_IO, "cannot write 'test sink': %zu records in", k->qn / k->record_size);
    }
    size_t bytes = (size_t)count * k->record_size;
    if (k->qn + bytes > k->qcap) {
        k->qcap = 2 * (k->qn + bytes);
        k->q = realloc(k->q, k->qcap);
        if (!k->q) /* not cmocka's assert: this may run on a worker thread, where its longjmp may not */
            abort();
    }
    memcpy(k->q + k->qn, records, bytes);
    for (uint64_t i = 0; i < count; i++) {
        uint32_t px;
        memcpy(&px, k->q + k->qn + i * k->record_size + k->off_pixel, 4);
        if (px < k->last_pixel)
            k->out_of_order = 1;
        k->last_pixel = px;
    }
    k->qn += bytes;
    return PM_OK;
}

static pm_result_t got_direct(void *user, uint32_t y0, uint32_t rows, const double *rgb)
{
    sink_t *k = user;
    for (uint32_t y = y0; y < y0 + rows; y++)
        k->rows_seen[y]++;
    memcpy(k->direct + (size_t)y0 * 8 * 3, rgb, (size_t)rows * 8 * 3 * sizeof *rgb);
    return PM_OK;
}

/* Traces the closed box at 8 x height (0: the scene's 8) into k; fail_after as in sink_t.
 * Returns pm_eye_trace's result. */
static pm_result_t trace_h(const pm_scene_t *s, const pm_rt_t *rt, int threads, int schedule, uint32_t height,
                           int fail_after, sink_t *k, pm_eye_stats_t *x)
{
    pm_eye_options_t o = {.mode = PM_EYE_GATHER,
                          .height = height,
                          .schedule = schedule,
                          .primary = 1,
                          .light_samples = 4,
                          .seed = 1,
                          .isa = pm_cpu_best_isa(),
                          .threads = threads};
    pm_eye_t *e;
    if (pm_eye_create(s, rt, &o, &e) != PM_OK)
        fail_msg("%s", pm_error_message());
    const pm_eye_info_t *in = pm_eye_info(e);
    assert_int_equal(in->width, 8);
    assert_int_equal(in->spp, 16);                                          /* the scene's render.spp */
    assert_int_equal(in->channels, pm_schema_required(&pm_queries_schema)); /* Lambertian: no material, no direction */
    assert_int_equal(in->record_size, 40);
    memset(k, 0, sizeof *k);
    k->record_size = in->record_size;
    k->off_pixel = pm_schema_offset(&pm_queries_schema, in->channels, PM_QUERY_PIXEL);
    k->fail_after = fail_after;
    k->caller = pthread_self();
    const pm_eye_sink_t sink = {got_queries, got_direct, NULL, k};
    pm_result_t r = pm_eye_trace(e, &sink, x);
    pm_eye_destroy(e);
    return r;
}

static void trace(const pm_scene_t *s, const pm_rt_t *rt, int threads, int schedule, sink_t *k, pm_eye_stats_t *x)
{
    if (trace_h(s, rt, threads, schedule, 0, 0, k, x) != PM_OK)
        fail_msg("%s", pm_error_message());
}

/* The closed box and its Embree scene, for every test here. */
static void load_box(pm_scene_t *s, pm_rt_t *rt)
{
    if (pm_scene_load(CLOSED_BOX, s) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(pm_rt_create(s, 0, 2, rt), PM_OK);
}

static void test_eyetrace_closed_box(void **state)
{
    pm_scene_t s;
    pm_rt_t rt;
    load_box(&s, &rt);
    sink_t a, b;
    pm_eye_stats_t xa, xb;
    trace(&s, &rt, 1, PM_EYE_INTERLEAVE, &a, &xa);
    /* a closed box: every pixel sends 16 secondary rays and each finds a wall */
    assert_int_equal(xa.primary_rays, 64);
    assert_int_equal(xa.secondary_rays, 64 * 16);
    assert_int_equal(xa.queries, 64 * 16);
    assert_int_equal(a.qn, 64 * 16 * 40);
    assert_false(a.out_of_order);
    for (int y = 0; y < 8; y++)
        assert_int_equal(a.rows_seen[y], 1);
    for (int i = 0; i < 64; i++)
        assert_true(a.direct[3 * i] > 0.0); /* the point light reaches every wall in view */
    for (int sched = PM_EYE_INTERLEAVE; sched <= PM_EYE_DYNAMIC; sched++) {
        trace(&s, &rt, 3, sched, &b, &xb);
        assert_int_equal(b.qn, a.qn);
        assert_memory_equal(b.q, a.q, a.qn);
        assert_memory_equal(b.direct, a.direct, sizeof a.direct);
        free(b.q);
    }
    free(a.q);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
}

static void test_eyetrace_failures(void **state)
{
    pm_scene_t s;
    pm_rt_t rt;
    load_box(&s, &rt);
    pm_eye_options_t o = {.mode = PM_EYE_GATHER, .primary = 1, .spp = 6, .isa = PM_ISA_SCALAR, .threads = 2};
    pm_eye_t *e = (pm_eye_t *)&o;
    assert_int_equal(pm_eye_create(&s, &rt, &o, &e), PM_ERR_USAGE);
    assert_null(e);
    assert_non_null(strstr(pm_error_message(), "--spp 6 is not a positive multiple of 4"));

    /* the sink fails past 200 records, in the second row (128 a row): the trace stops with its
     * code and message */
    o.spp = 0;
    assert_int_equal(pm_eye_create(&s, &rt, &o, &e), PM_OK);
    sink_t k = {.record_size = pm_eye_info(e)->record_size, .fail_after = 200};
    const pm_eye_sink_t sink = {got_queries, got_direct, NULL, &k};
    pm_eye_stats_t x;
    assert_int_equal(pm_eye_trace(e, &sink, &x), PM_ERR_IO);
    assert_string_equal(pm_error_message(), "cannot write 'test sink': 128 records in");
    for (int y = 0; y < 8; y++)
        assert_int_equal(k.rows_seen[y], 0); /* the band's direct rows never went out */
    free(k.q);
    pm_eye_destroy(e);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
}

static void test_eyetrace_bands(void **state)
{
    pm_scene_t s;
    pm_rt_t rt;
    load_box(&s, &rt);
    sink_t *a = calloc(1, sizeof *a), *b = calloc(1, sizeof *b);
    assert_non_null(a);
    assert_non_null(b);
    pm_eye_stats_t xa, xb;
    /* 80 rows: bands of 32, 32 and 16; 65: the last band one row, fewer than the threads */
    static const uint32_t heights[] = {MAX_ROWS, 65};
    for (size_t hi = 0; hi < sizeof heights / sizeof heights[0]; hi++) {
        uint32_t h = heights[hi];
        assert_int_equal(trace_h(&s, &rt, 1, PM_EYE_INTERLEAVE, h, 0, a, &xa), PM_OK);
        assert_int_equal(xa.queries, 8 * h * 16);
        assert_int_equal(a->qn, (size_t)8 * h * 16 * 40);
        assert_false(a->out_of_order);
        assert_int_equal(a->off_caller, 0); /* one thread: the caller's */
        for (uint32_t y = 0; y < MAX_ROWS; y++)
            assert_int_equal(a->rows_seen[y], y < h);
        for (int threads = 2; threads <= 3; threads++)
            for (int sched = PM_EYE_INTERLEAVE; sched <= PM_EYE_DYNAMIC; sched++) {
                assert_int_equal(trace_h(&s, &rt, threads, sched, h, 0, b, &xb), PM_OK);
                assert_int_equal(b->qn, a->qn);
                assert_memory_equal(b->q, a->q, a->qn);
                assert_memory_equal(b->direct, a->direct, sizeof a->direct);
                for (uint32_t y = 0; y < MAX_ROWS; y++)
                    assert_int_equal(b->rows_seen[y], y < h);
                /* the first two bands went out on a worker while the next was traced, the last on
                 * the caller after it */
                assert_int_equal(b->off_caller, 64);
                free(b->q);
            }
        free(a->q);
    }
    /* The sink fails once, in the first band's records (row 5) or the second's (row 37 of 32 to
     * 63), delivered on a worker while the next band is traced: the trace returns that failure
     * with its message, and nothing after it goes out (the band's own direct rows included). */
    static const struct {
        int row, direct_rows;
    } fails[] = {{5, 0}, {37, 32}};
    for (size_t f = 0; f < sizeof fails / sizeof fails[0]; f++)
        for (int sched = PM_EYE_INTERLEAVE; sched <= PM_EYE_DYNAMIC; sched++) {
            int row = fails[f].row;
            assert_int_equal(trace_h(&s, &rt, 2, sched, MAX_ROWS, row * 8 * 16, b, &xb), PM_ERR_IO);
            char want[64];
            snprintf(want, sizeof want, "cannot write 'test sink': %d records in", row * 8 * 16);
            assert_string_equal(pm_error_message(), want);
            assert_int_equal(b->failed_off, 1);
            assert_int_equal(b->qn, (size_t)row * 8 * 16 * 40);
            for (int y = 0; y < MAX_ROWS; y++)
                assert_int_equal(b->rows_seen[y], y < fails[f].direct_rows);
            free(b->q);
        }
    free(a);
    free(b);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_eyetrace_closed_box),
    cmocka_unit_test(test_eyetrace_failures),
    cmocka_unit_test(test_eyetrace_bands),
};
UNIT_GROUP(unit_eyetrace, "eyetrace", tests);
