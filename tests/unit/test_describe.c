/* test_describe.c: formats/describe, what pm-info prints: a golden header as JSON (count, record
 * size, channel names, provenance), the records as text against the golden text, the checked
 * JSON of a whole file, and the errors (a value that is not UTF-8, --json with --records). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "formats/describe.h"
#include "formats/formats.h"
#include "unit.h"

/* The whole of a file as a NUL-terminated string (the caller frees it). */
static char *slurp(FILE *f)
{
    assert_int_equal(fseek(f, 0, SEEK_END), 0);
    long n = ftell(f);
    assert_true(n >= 0);
    rewind(f);
    char *s = malloc((size_t)n + 1);
    assert_non_null(s);
    assert_int_equal(fread(s, 1, (size_t)n, f), (size_t)n);
    s[n] = '\0';
    return s;
}

static void test_describe_header_json(void **state)
{
    pm_reader_t *r;
    assert_int_equal(pm_reader_open("tests/golden/queries-all.pm", NULL, 0, &r), PM_OK);
    json_t *j = NULL;
    pm_result_t res = pm_describe_header_json("q.pm", pm_reader_header(r), pm_reader_header_text(r), &j);
    pm_reader_close(r);
    if (res != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_string_equal(json_string_value(json_object_get(j, "file")), "q.pm");
    assert_string_equal(json_string_value(json_object_get(j, "format")), "queries");
    assert_string_equal(json_string_value(json_object_get(j, "version")), "2.0");
    assert_int_equal(json_integer_value(json_object_get(j, "count")), 7);
    assert_int_equal(json_integer_value(json_object_get(j, "record_size")), 54);
    static const char *const names[] = {"position", "normal", "weight", "pixel", "material", "direction"};
    json_t *ch = json_object_get(j, "channels");
    assert_int_equal(json_array_size(ch), 6);
    for (size_t i = 0; i < 6; i++)
        assert_string_equal(json_string_value(json_array_get(ch, i)), names[i]);
    assert_int_equal(json_array_size(json_object_get(j, "bounds")), 6);
    assert_true(json_real_value(json_array_get(json_object_get(j, "bounds"), 1)) == -2.0);
    assert_string_equal(json_string_value(json_object_get(j, "software")), "pmtk 0.1.0");
    assert_string_equal(json_string_value(json_array_get(json_object_get(j, "commands"), 0)),
                        "pm-testgen queries --all");
    json_t *keys = json_object_get(j, "keys");
    assert_string_equal(json_string_value(json_object_get(keys, "SCENE")), "test xxh3:0123456789abcdef");
    assert_string_equal(json_string_value(json_object_get(keys, "width")), "8");
    json_decref(j);
}

/* An INPUT line splits at its last " xxh3:", so that a path with spaces survives. */
static void test_describe_inputs(void **state)
{
    pm_header_t h;
    pm_header_init(&h, &pm_radiance_schema);
    assert_int_equal(pm_header_add(&h, "INPUT", "a b xxh3:1.pm xxh3:00000000000000ff"), PM_OK);
    json_t *j = NULL;
    assert_int_equal(pm_describe_header_json("r.pm", &h, "", &j), PM_OK);
    json_t *in = json_array_get(json_object_get(j, "inputs"), 0);
    assert_string_equal(json_string_value(json_object_get(in, "path")), "a b xxh3:1.pm");
    assert_string_equal(json_string_value(json_object_get(in, "hash")), "xxh3:00000000000000ff");
    assert_true(json_is_null(json_object_get(j, "software"))); /* none in the text */
    json_decref(j);
    pm_header_free(&h);
}

static void test_describe_not_utf8(void **state)
{
    pm_header_t h;
    pm_header_init(&h, &pm_photons_schema);
    assert_int_equal(pm_header_set(&h, "note", "caf\xe9"), PM_OK);
    json_t *j = NULL;
    assert_int_equal(pm_describe_header_json("p.pm", &h, "", &j), PM_ERR_INPUT);
    assert_null(j);
    assert_string_equal(pm_error_message(), "cannot describe 'p.pm' as JSON: note is not UTF-8");
    pm_header_free(&h);
}

static void test_describe_records_text(void **state)
{
    FILE *f = tmpfile();
    assert_non_null(f);
    pm_describe_options_t o = {.records = 1, .limit = -1};
    uint64_t n = 0;
    if (pm_describe_file(f, "tests/golden/photonmap-all.pm", &o, &n) != PM_OK)
        fail_msg("%s", pm_error_message());
    assert_int_equal(n, 7);
    char *got = slurp(f);
    fclose(f);
    FILE *g = fopen("tests/golden/photonmap-all.txt", "rb");
    assert_non_null(g);
    char *want = slurp(g);
    fclose(g);
    assert_string_equal(got, want);
    free(got);
    free(want);
}

static void test_describe_file_json(void **state)
{
    FILE *f = tmpfile();
    assert_non_null(f);
    pm_describe_options_t o = {.json = 1, .limit = -1};
    uint64_t n = 0;
    assert_int_equal(pm_describe_file(f, "tests/golden/radiance-required.pm", &o, &n), PM_OK);
    assert_int_equal(n, 12); /* a 4 x 3 image */
    o.header_only = 1;
    assert_int_equal(pm_describe_file(f, "tests/golden/radiance-required.pm", &o, &n), PM_OK);
    assert_int_equal(n, 0);
    rewind(f);
    json_error_t e;
    json_t *full = json_loadf(f, JSON_DISABLE_EOF_CHECK, &e), *head = json_loadf(f, JSON_DISABLE_EOF_CHECK, &e);
    fclose(f);
    assert_non_null(full);
    assert_non_null(head);
    assert_true(json_is_true(json_object_get(full, "checked")));
    const char *sum = json_string_value(json_object_get(full, "checksum"));
    assert_non_null(sum);
    assert_int_equal(strlen(sum), strlen("xxh3:") + 16);
    assert_true(json_is_false(json_object_get(head, "checked")));
    assert_null(json_object_get(head, "checksum"));
    json_decref(full);
    json_decref(head);

    o = (pm_describe_options_t){.json = 1, .records = 1, .limit = -1};
    assert_int_equal(pm_describe_file(stdout, "tests/golden/radiance-required.pm", &o, &n), PM_ERR_USAGE);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_describe_header_json), cmocka_unit_test(test_describe_inputs),
    cmocka_unit_test(test_describe_not_utf8),    cmocka_unit_test(test_describe_records_text),
    cmocka_unit_test(test_describe_file_json),
};
UNIT_GROUP(unit_describe, "describe", tests);
