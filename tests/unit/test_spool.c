/* test_spool.c: the record spool of common/base/spool.h: records come back in order and
 * whole from memory, across chunk boundaries, and from a spill file; a failing spill or emit
 * stops with its message; the folder a spool goes in. Also base/memory.h's reuse of freed
 * mappings, which a spool's chunks in a stream of frames rely on. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "base/error.h"
#include "base/memory.h"
#include "base/spool.h"
#include "unit.h"

/* Collects replayed records into one buffer. */
typedef struct {
    unsigned char *p;
    size_t n, cap, calls;
    size_t record_size;
    int fail_at; /* call number that fails (1-based), 0 for none */
} collect_t;

static pm_result_t collect(void *user, const void *records, uint64_t count)
{
    collect_t *c = user;
    if (c->fail_at && ++c->calls == (size_t)c->fail_at)
        return pm_error_set(PM_ERR_IO, "cannot write 'sink': call %zu", c->calls);
    size_t bytes = (size_t)count * c->record_size;
    if (c->n + bytes > c->cap) {
        c->cap = 2 * (c->n + bytes);
        c->p = realloc(c->p, c->cap);
        assert_non_null(c->p);
    }
    memcpy(c->p + c->n, records, bytes);
    c->n += bytes;
    return PM_OK;
}

/* count records of rs bytes numbered from 0: byte k of record i is (i * 7 + k) & 255. */
static unsigned char *make_records(size_t count, size_t rs)
{
    unsigned char *p = malloc(count * rs);
    assert_non_null(p);
    for (size_t i = 0; i < count; i++)
        for (size_t k = 0; k < rs; k++)
            p[i * rs + k] = (unsigned char)((i * 7 + k) & 255);
    return p;
}

/* Adds count records in uneven batches (1, 2, 3, ... records), replays, compares. */
static void round_trip(size_t rs, size_t count, size_t mem_max, int expect_spill)
{
    unsigned char *recs = make_records(count, rs);
    pm_spool_t sp;
    pm_spool_init(&sp, rs, mem_max, unit_tmpdir());
    for (size_t at = 0, batch = 1; at < count; at += batch, batch++) {
        size_t n = count - at < batch ? count - at : batch;
        if (pm_spool_add(&sp, recs + at * rs, n) != PM_OK)
            fail_msg("%s", pm_error_message());
        batch = n;
    }
    assert_int_equal(sp.count, count);
    assert_int_equal(pm_spool_spilled(&sp), expect_spill);
    for (int pass = 0; pass < 2; pass++) { /* a replay leaves the spool as it was */
        collect_t c = {.record_size = rs};
        assert_int_equal(pm_spool_replay(&sp, collect, &c), PM_OK);
        assert_int_equal(c.n, count * rs);
        assert_memory_equal(c.p, recs, count * rs);
        free(c.p);
    }
    pm_spool_free(&sp);
    assert_int_equal(sp.count, 0);
    free(recs);
}

static void test_spool_memory(void **state)
{
    round_trip(3, 0, 1 << 20, 0);              /* nothing added: nothing replayed */
    round_trip(40, 1000, 1 << 20, 0);          /* one chunk */
    round_trip(3, 300000, (size_t)1 << 30, 0); /* 3-byte records over three chunks of 2^17 */
}

static void test_spool_spill(void **state)
{
    round_trip(40, 1000, 0, 1);           /* --spool-mem 0: the first record spills */
    round_trip(12, 5000, 12 * 1000, 1);   /* memory first, then the file */
    round_trip(3, 300000, 3 * 200000, 1); /* spills with two chunks held */
}

static void test_spool_failures(void **state)
{
    unsigned char *recs = make_records(1000, 40);
    pm_spool_t sp;
    /* an emit that fails stops the replay and its message is the one returned */
    pm_spool_init(&sp, 40, 1 << 20, unit_tmpdir());
    for (int i = 0; i < 3; i++)
        assert_int_equal(pm_spool_add(&sp, recs, 1000), PM_OK);
    collect_t c = {.record_size = 40, .fail_at = 1};
    assert_int_equal(pm_spool_replay(&sp, collect, &c), PM_ERR_IO);
    assert_string_equal(pm_error_message(), "cannot write 'sink': call 1");
    free(c.p);
    pm_spool_free(&sp);

    /* a spill file that cannot grow (a file-size limit, as on a full disk): PM_ERR_IO naming
     * the folder and the reason */
    struct rlimit old;
    assert_int_equal(getrlimit(RLIMIT_FSIZE, &old), 0);
    struct rlimit small = {4096, old.rlim_max};
    void (*old_handler)(int) = signal(SIGXFSZ, SIG_IGN); /* EFBIG rather than the signal */
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &small), 0);
    pm_spool_init(&sp, 40, 0, unit_tmpdir());
    pm_result_t r = PM_OK;
    for (int i = 0; i < 20 && r == PM_OK; i++)
        r = pm_spool_add(&sp, recs, 1000);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &old), 0);
    signal(SIGXFSZ, old_handler);
    assert_int_equal(r, PM_ERR_IO);
    char want[1200];
    snprintf(want, sizeof want, "cannot write the spool file in '%s': File too large", unit_tmpdir());
    assert_string_equal(pm_error_message(), want);
    pm_spool_free(&sp);
    free(recs);
}

static void test_spool_dir(void **state)
{
    char dir[64];
    pm_spool_dir_for("out/q.pm", dir, sizeof dir);
    assert_string_equal(dir, "out");
    pm_spool_dir_for("/q.pm", dir, sizeof dir);
    assert_string_equal(dir, "/");
    pm_spool_dir_for("q.pm", dir, sizeof dir);
    assert_string_equal(dir, ".");
    const char *tmp = getenv("TMPDIR");
    char *saved = tmp ? strdup(tmp) : NULL;
    setenv("TMPDIR", "/var/spool-test", 1);
    pm_spool_dir_for("-", dir, sizeof dir);
    assert_string_equal(dir, "/var/spool-test");
    unsetenv("TMPDIR");
    pm_spool_dir_for("-", dir, sizeof dir);
    assert_string_equal(dir, "/tmp");
    if (saved)
        setenv("TMPDIR", saved, 1);
    free(saved);
}

/* With reuse on, a freed mapping serves the next request it fits (the same address, its
 * contents kept); a larger request grows it (its contents kept); off, nothing is kept; a block
 * past the room is unmapped. */
static void test_memory_reuse(void **state)
{
    (void)state;
    const size_t mib = (size_t)1 << 20;
    pm_memory_reuse(16 * mib);
    /* 64 bytes less than 6 MiB: with the block's header, a mapping of 6 MiB exactly */
    unsigned char *a = pm_alloc_aligned(6 * mib - 64);
    assert_non_null(a);
    a[5 * mib] = 0xab;
    pm_free_aligned(a);
    unsigned char *b = pm_alloc_aligned(5 * mib); /* fits the 6 MiB mapping */
    assert_ptr_equal(b, a);
    assert_int_equal(b[5 * mib], 0xab);
    b[0] = 1;
    pm_free_aligned(b);
    /* larger than any kept: the kept 6 MiB grows into an 8 MiB mapping, its pages moved (what
     * they held is there still), the rest fresh */
    unsigned char *c = pm_alloc_aligned(7 * mib);
    assert_non_null(c);
    assert_int_equal(c[5 * mib], 0xab);
    c[7 * mib - 1] = 2;
    unsigned char *d = pm_alloc_aligned(6 * mib - 64); /* nothing kept now: a mapping of its own */
    assert_non_null(d);
    assert_true(d != c);
    d[6 * mib - 65] = 4;
    assert_int_equal(c[7 * mib - 1], 2);
    pm_free_aligned(c);
    pm_free_aligned(d);
    /* both kept: a request of 7 MiB takes the 8 MiB one, one of 5 MiB the 6 MiB one */
    unsigned char *e8 = pm_alloc_aligned(7 * mib), *e6 = pm_alloc_aligned(5 * mib);
    assert_ptr_equal(e8, c);
    assert_ptr_equal(e6, d);
    pm_free_aligned(e8);
    pm_free_aligned(e6);
    /* a grown mapping grows again, its contents kept each time (one area however often it
     * grows: kernels before 6.17 do not move a range that spans two) */
    unsigned char *g2 = pm_alloc_aligned(9 * mib); /* the kept 8 MiB one grown to 10 MiB */
    assert_non_null(g2);
    assert_int_equal(g2[5 * mib], 0xab);
    assert_int_equal(g2[7 * mib - 1], 2);
    g2[9 * mib] = 7;
    pm_free_aligned(g2);
    unsigned char *g3 = pm_alloc_aligned(13 * mib); /* the 10 MiB one grown to 14 MiB */
    assert_non_null(g3);
    assert_int_equal(g3[5 * mib], 0xab);
    assert_int_equal(g3[9 * mib], 7);
    g3[13 * mib] = 8;
    pm_free_aligned(g3); /* kept; the 6 MiB one, oldest, goes to make room */
    /* larger than the room: the kept 14 MiB one grown, then unmapped when freed, not kept */
    unsigned char *big = pm_alloc_aligned(40 * mib);
    assert_non_null(big);
    assert_int_equal(big[13 * mib], 8);
    pm_free_aligned(big);
    pm_memory_reuse(0);                                                       /* off: the kept ones go */
    unsigned char *e = pm_alloc_aligned(2 * mib), *s = pm_alloc_aligned(100); /* small: the heap, never kept */
    assert_non_null(e);
    assert_non_null(s);
    memset(e, 3, 2 * mib);
    pm_free_aligned(s);
    pm_free_aligned(e);
}

/* The start a re-executed program counts its budget from: PMTK_START_S when it is a time
 * before now and within a minute of it, else now; taken out of the environment either way. */
static void test_memory_started(void **state)
{
    (void)state;
    const struct {
        const char *value; /* PMTK_START_S, or NULL: unset */
        double want;       /* against now = 100 */
    } cases[] = {
        {"99.25", 99.25}, /* the first start, 0.75 s before */
        {NULL, 100.0},    /* not re-executed */
        {"100.5", 100.0}, /* later than now: not this program's */
        {"30", 100.0},    /* more than a minute back */
        {"99.5x", 100.0}, /* not a number */
        {"", 100.0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        if (cases[i].value)
            setenv("PMTK_START_S", cases[i].value, 1);
        else
            unsetenv("PMTK_START_S");
        assert_true(pm_memory_started(100.0) == cases[i].want);
        assert_null(getenv("PMTK_START_S"));
    }
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_spool_memory), cmocka_unit_test(test_spool_spill),  cmocka_unit_test(test_spool_failures),
    cmocka_unit_test(test_spool_dir),    cmocka_unit_test(test_memory_reuse), cmocka_unit_test(test_memory_started),
};
UNIT_GROUP(unit_spool, "spool", tests);
