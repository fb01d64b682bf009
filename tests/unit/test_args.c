/* test_args.c: the option parser: types, ranges, @files, errors. */
#include <stdio.h>
#include <string.h>

#include "base/args.h"
#include "unit.h"

typedef struct {
    int flag, choice;
    int64_t n;
    double x;
    const char *s;
} opts_t;

static const char *const choices[] = {"none", "morton", "hilbert", NULL};

static pm_result_t parse(opts_t *o, pm_args_t *a, int argc, char **argv)
{
    const pm_option_t t[] = {
        {"flag", 'f', PM_OPT_FLAG, &o->flag, NULL, "a flag", 1, 0, NULL},
        {"count", 'n', PM_OPT_INT, &o->n, "N", "a count", 0, 1000, NULL},
        {"radius", 0, PM_OPT_DOUBLE, &o->x, "R", "a radius", 0, 1e30, NULL},
        {"name", 0, PM_OPT_STRING, &o->s, "S", "a name", 1, 0, NULL},
        {"order", 0, PM_OPT_CHOICE, &o->choice, "O", "an order", 1, 0, choices},
        {0},
    };
    const pm_cli_t cli = {"t", "[options]", "test", t, 0, -1, NULL};
    return pm_args_parse(&cli, argc, argv, a);
}

static void test_args_types(void **state)
{
    opts_t o = {0};
    pm_args_t a;
    char *argv[] = {"t", "-f",      "--count=5e2", "--radius", "0.25", "pos1",   "--name",
                    "x", "--order", "hilbert",     "-",        "--",   "--count"};
    assert_int_equal(parse(&o, &a, 13, argv), PM_OK);
    assert_int_equal(o.flag, 1);
    assert_int_equal(o.n, 500);
    assert_true(o.x == 0.25);
    assert_string_equal(o.s, "x");
    assert_int_equal(o.choice, 2);
    assert_int_equal(a.nargs, 3);
    assert_string_equal(a.args[0], "pos1");
    assert_string_equal(a.args[1], "-");
    assert_string_equal(a.args[2], "--count");
    pm_args_free(&a);
}

static void expect_usage_error(char *arg1, char *arg2, const char *needle)
{
    opts_t o = {0};
    pm_args_t a;
    char *argv[] = {"t", arg1, arg2};
    assert_int_equal(parse(&o, &a, arg2 ? 3 : 2, argv), PM_ERR_USAGE);
    assert_non_null(strstr(pm_error_message(), needle));
    pm_args_free(&a);
}

static void test_args_errors(void **state)
{
    expect_usage_error("--bogus", NULL, "unknown option '--bogus'");
    expect_usage_error("--count", "12x", "'12x' is not an integer");
    expect_usage_error("--count", "1001", "outside");
    expect_usage_error("--count", NULL, "needs a value");
    expect_usage_error("--radius", "nan", "not a finite number");
    expect_usage_error("--radius", "-1", "outside");
    expect_usage_error("--order", "zorder", "'zorder' is not one of none|morton|hilbert");
    expect_usage_error("--flag=1", NULL, "takes no value");
    expect_usage_error("--count", "0x10", "'0x10' is not an integer");
    expect_usage_error("--count", " 5", "' 5' is not an integer");
}

static void test_args_atfile(void **state)
{
    char path[256];
    snprintf(path, sizeof path, "%s/opts", unit_tmpdir());
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs("# settings\n--count 7   # trailing comment\n--order morton\n", f);
    fclose(f);
    char at[260];
    snprintf(at, sizeof at, "@%s", path);
    opts_t o = {0};
    pm_args_t a;
    char *argv[] = {"t", at, "--radius", "2"};
    assert_int_equal(parse(&o, &a, 4, argv), PM_OK);
    assert_int_equal(o.n, 7);
    assert_int_equal(o.choice, 1);
    assert_true(o.x == 2.0);
    pm_args_free(&a);
    char *argv2[] = {"t", "@/nonexistent/opts"};
    assert_int_equal(parse(&o, &a, 2, argv2), PM_ERR_USAGE);
    pm_args_free(&a);
    /* after "--" and as an option's value, @ is literal */
    char *argv3[] = {"t", "--name", "@x", "--", at};
    assert_int_equal(parse(&o, &a, 5, argv3), PM_OK);
    assert_string_equal(o.s, "@x");
    assert_int_equal(a.nargs, 1);
    assert_string_equal(a.args[0], at);
    pm_args_free(&a);
    /* a file naming itself stops */
    f = fopen(path, "w");
    fprintf(f, "--count 1 %s\n", at);
    fclose(f);
    char *argv4[] = {"t", at};
    assert_int_equal(parse(&o, &a, 2, argv4), PM_ERR_USAGE);
    assert_non_null(strstr(pm_error_message(), "does one name itself"));
    pm_args_free(&a);
}

/* pm_args_record leaves out exactly the words of the options named, by where they stand (the
 * same text as another option's value stays), and keeps an @FILE word whole. */
static void test_args_record(void **state)
{
    char path[256], at[260];
    snprintf(path, sizeof path, "%s/rec", unit_tmpdir());
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs("--count 9\n", f);
    fclose(f);
    snprintf(at, sizeof at, "@%s", path);
    opts_t o = {0};
    pm_args_t a;
    char *argv[] = {"t", "--count", "5", "pos", "--count=6", "-n", "7", "-n8", "--radius", "5", at, "--", "--count"};
    assert_int_equal(parse(&o, &a, 13, argv), PM_OK);
    assert_int_equal(o.n, 9);
    const void *skip[] = {&o.n};
    int rc = 0;
    char **rv = NULL;
    assert_int_equal(pm_args_record(&a, argv, skip, 1, &rc, &rv), PM_OK);
    const char *want[] = {"t", "pos", "--radius", "5", at, "--", "--count"};
    assert_int_equal(rc, 7);
    for (int i = 0; i < rc; i++)
        assert_string_equal(rv[i], want[i]);
    assert_ptr_equal(rv[3], argv[9]); /* the radius's "5", not the count's */
    assert_int_equal(pm_args_record(&a, argv, skip, 0, &rc, &rv), PM_OK);
    assert_int_equal(rc, 13);
    pm_args_free(&a);
    /* a flag (as the stages leave out -q/--quiet) and an option of a value (--stats), each in
     * both spellings, go with their words; the same text as a positional stays */
    char *argv2[] = {"t", "-f", "pos", "--name", "s.json", "--flag", "--name=t.json", "--radius", "1", "--", "-f"};
    assert_int_equal(parse(&o, &a, 11, argv2), PM_OK);
    const void *skip2[] = {&o.flag, &o.s};
    assert_int_equal(pm_args_record(&a, argv2, skip2, 2, &rc, &rv), PM_OK);
    const char *want2[] = {"t", "pos", "--radius", "1", "--", "-f"};
    assert_int_equal(rc, 6);
    for (int i = 0; i < rc; i++)
        assert_string_equal(rv[i], want2[i]);
    assert_ptr_equal(rv[5], argv2[10]);
    pm_args_free(&a);
}

static void test_args_settings_round_trip(void **state)
{
    opts_t o = {0};
    pm_args_t a;
    const pm_option_t t[] = {
        {"name", 0, PM_OPT_STRING, &o.s, "S", "a name", 1, 0, NULL},
        {"count", 'n', PM_OPT_INT, &o.n, "N", "a count", 0, 1000, NULL},
        {0},
    };
    const pm_cli_t cli = {"t", "[options]", "test", t, 0, -1, NULL};
    o.s = "it's a #name @with\\ blanks";
    o.n = 12;
    char path[256], at[260];
    snprintf(path, sizeof path, "%s/settings", unit_tmpdir());
    snprintf(at, sizeof at, "@%s", path);
    FILE *f = fopen(path, "w");
    pm_args_print_settings(&cli, f);
    fclose(f);
    opts_t back = {0};
    const pm_option_t t2[] = {
        {"name", 0, PM_OPT_STRING, &back.s, "S", "a name", 1, 0, NULL},
        {"count", 'n', PM_OPT_INT, &back.n, "N", "a count", 0, 1000, NULL},
        {0},
    };
    const pm_cli_t cli2 = {"t", "[options]", "test", t2, 0, -1, NULL};
    char *argv[] = {"t", at};
    assert_int_equal(pm_args_parse(&cli2, 2, argv, &a), PM_OK);
    assert_string_equal(back.s, o.s);
    assert_int_equal(back.n, 12);
    pm_args_free(&a);
}

static void test_args_range(void **state)
{
    uint64_t b, e;
    assert_int_equal(pm_args_parse_range("10:20", &b, &e), PM_OK);
    assert_true(b == 10 && e == 20);
    assert_int_equal(pm_args_parse_range(":5", &b, &e), PM_OK);
    assert_true(b == 0 && e == 5);
    assert_int_equal(pm_args_parse_range("5:", &b, &e), PM_OK);
    assert_true(b == 5 && e == INT64_MAX);
    assert_int_equal(pm_args_parse_range("20:10", &b, &e), PM_ERR_USAGE);
    assert_int_equal(pm_args_parse_range("20", &b, &e), PM_ERR_USAGE);
    assert_int_equal(pm_args_parse_range("a:b", &b, &e), PM_ERR_USAGE);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_args_types),  cmocka_unit_test(test_args_errors),
    cmocka_unit_test(test_args_atfile), cmocka_unit_test(test_args_range),
    cmocka_unit_test(test_args_record), cmocka_unit_test(test_args_settings_round_trip),
};
UNIT_GROUP(unit_args, "args", tests);
