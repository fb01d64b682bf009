/* test_atomic.c: atomic outputs (common/base/atomic.h): output sets renamed together or not
 * at all, nested sets, temporary names within NAME_MAX, links followed, special files left as
 * they are, and which paths name one file. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/atomic.h"
#include "unit.h"

/* A path in the test directory. */
static const char *tmp_path(char *buf, size_t cap, const char *name)
{
    snprintf(buf, cap, "%s/atomic-%s", unit_tmpdir(), name);
    return buf;
}

static int exists(const char *p)
{
    struct stat sb;
    return lstat(p, &sb) == 0;
}

static void write_text(const char *path, const char *text)
{
    pm_atomic_t a;
    assert_int_equal(pm_atomic_open(path, &a), PM_OK);
    assert_true(fputs(text, a.f) >= 0);
    assert_int_equal(pm_atomic_commit(&a), PM_OK);
}

static void test_atomic_set(void **state)
{
    char a[512], b[512];
    tmp_path(a, sizeof a, "set-a"), tmp_path(b, sizeof b, "set-b");
    unlink(a), unlink(b);
    /* committed in a set: nothing at the final names until the set commits */
    pm_atomic_set_t s, inner;
    pm_atomic_set_begin(&s);
    write_text(a, "a\n");
    pm_atomic_set_begin(&inner); /* joins s */
    write_text(b, "b\n");
    assert_int_equal(pm_atomic_set_commit(&inner), PM_OK);
    assert_false(exists(a) || exists(b));
    assert_int_equal(pm_atomic_set_commit(&s), PM_OK);
    assert_true(exists(a) && exists(b));
    /* aborted: neither name changes, and no temporary file is left */
    unlink(a), unlink(b);
    pm_atomic_set_begin(&s);
    write_text(a, "a\n");
    write_text(b, "b\n");
    assert_int_equal(pm_atomic_set_end(&s, PM_ERR_IO), PM_ERR_IO);
    assert_false(exists(a) || exists(b));
    /* a refused target renames nothing: b became a directory meanwhile */
    pm_atomic_set_begin(&s);
    write_text(a, "a\n");
    write_text(b, "b\n");
    assert_int_equal(mkdir(b, 0700), 0);
    assert_int_equal(pm_atomic_set_commit(&s), PM_ERR_IO);
    assert_non_null(strstr(pm_error_message(), "no longer a regular file"));
    assert_false(exists(a));
    rmdir(b);
    /* no set open any more: a commit renames at once */
    write_text(a, "a\n");
    assert_true(exists(a));
    unlink(a);
}

static void test_atomic_names(void **state)
{
    char p[600], link[512], target[512];
    /* a 255-byte name is legal, and so must its temporary be */
    int n = snprintf(p, sizeof p, "%s/", unit_tmpdir());
    memset(p + n, 'x', 255);
    p[n + 255] = '\0';
    write_text(p, "long\n");
    assert_true(exists(p));
    unlink(p);
    /* a link stays a link, and its target gets the output */
    tmp_path(target, sizeof target, "target");
    tmp_path(link, sizeof link, "link");
    unlink(link), unlink(target);
    assert_int_equal(symlink("atomic-target", link), 0);
    write_text(link, "through the link\n");
    struct stat sb;
    assert_int_equal(lstat(link, &sb), 0);
    assert_true(S_ISLNK(sb.st_mode));
    assert_int_equal(lstat(target, &sb), 0);
    assert_true(S_ISREG(sb.st_mode) && sb.st_size == 17);
    /* a FIFO is checked without being opened (which would wait for a reader) */
    tmp_path(p, sizeof p, "fifo");
    unlink(p);
    assert_int_equal(mkfifo(p, 0600), 0);
    assert_int_equal(pm_atomic_check(p), PM_OK);
    assert_int_equal(lstat(p, &sb), 0);
    assert_true(S_ISFIFO(sb.st_mode));
    unlink(p);
    assert_int_equal(pm_atomic_check(unit_tmpdir()), PM_ERR_USAGE); /* a directory */
    unlink(link), unlink(target);
}

static void test_atomic_same_file(void **state)
{
    char a[512], a2[512], h[512], b[512];
    tmp_path(a, sizeof a, "same");
    snprintf(a2, sizeof a2, "%s/./atomic-same", unit_tmpdir());
    tmp_path(b, sizeof b, "other");
    tmp_path(h, sizeof h, "hard");
    unlink(a), unlink(h), unlink(b);
    assert_true(pm_atomic_same_file("-", "-"));
    assert_false(pm_atomic_same_file("-", a));
    assert_true(pm_atomic_same_file(a, a2)); /* not there yet: by name */
    assert_false(pm_atomic_same_file(a, b));
    write_text(a, "x\n");
    assert_int_equal(link(a, h), 0);
    assert_true(pm_atomic_same_file(a, h)); /* there: by device and inode */
    assert_false(pm_atomic_same_file(a, b));
    assert_false(pm_atomic_same_file("/dev/null", "/dev/null")); /* takes any number of outputs */
    unlink(a), unlink(h);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_atomic_set),
    cmocka_unit_test(test_atomic_names),
    cmocka_unit_test(test_atomic_same_file),
};
UNIT_GROUP(unit_atomic, "atomic", tests);
