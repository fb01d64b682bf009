/* test_engine.c: the render driver's library (common/engine/engine.h): the settings and their
 * usage errors, the COMMAND line a stage records, provenance verdicts (whole, missing, corrupt,
 * made otherwise, the scene's path no part of the identity, an input that changed), and
 * spawning (exit status and class, stderr captured, stdout through a pipe). */
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/error.h"
#include "engine/engine.h"
#include "formats/formats.h"
#include "formats/pmfile.h"
#include "unit.h"

static void test_engine_settings(void **state)
{
    (void)state;
    pm_settings_t s;
    pm_settings_init(&s);
    char *ok[] = {"PHOTONS=1000", "SHARDS=3", "photonmap.pm"};
    assert_int_equal(pm_settings_parse(&s, 3, ok), PM_OK);
    assert_string_equal(s.value[PM_P_PHOTONS], "1000");
    assert_string_equal(s.value[PM_P_MODE], "gather"); /* the default */
    assert_int_equal(s.shards, 3);
    assert_int_equal(s.ntargets, 1);
    assert_false(s.progressive);
    assert_int_equal(s.keep, PM_KEEP_ALL);
    pm_settings_init(&s);
    char *kb[] = {"KEEP=buffers"};
    assert_int_equal(pm_settings_parse(&s, 1, kb), PM_OK);
    assert_int_equal(s.keep, PM_KEEP_BUFFERS);

    pm_settings_init(&s);
    char *unknown[] = {"NOPE=1"};
    assert_int_equal(pm_settings_parse(&s, 1, unknown), PM_ERR_USAGE);
    assert_non_null(strstr(pm_error_message(), "unknown parameter 'NOPE' (known: ADAPTIVE ALPHA "));
    pm_settings_init(&s);
    char *choice[] = {"MODE=fast"};
    assert_int_equal(pm_settings_parse(&s, 1, choice), PM_ERR_USAGE);
    assert_string_equal(pm_error_message(), "bad value for MODE 'fast': expected one of gather direct-vis");
    pm_settings_init(&s);
    char *shards[] = {"SHARDS=0"};
    assert_int_equal(pm_settings_parse(&s, 1, shards), PM_ERR_USAGE);
    assert_string_equal(pm_error_message(), "bad value for SHARDS '0': expected a count of at least 1");
    pm_settings_init(&s);
    char *alpha[] = {"ALPHA=1"};
    assert_int_equal(pm_settings_parse(&s, 1, alpha), PM_ERR_USAGE);
    pm_settings_init(&s);
    char *keep[] = {"KEEP=image", "sorted.pm"};
    assert_int_equal(pm_settings_parse(&s, 2, keep), PM_ERR_USAGE);
    /* what makes a render progressive */
    char *passes1[] = {"PASSES=1"}, *passes2[] = {"PASSES=2"}, *time[] = {"TIME=2.5"};
    pm_settings_init(&s);
    assert_int_equal(pm_settings_parse(&s, 1, passes1), PM_OK);
    assert_false(s.progressive);
    pm_settings_init(&s);
    assert_int_equal(pm_settings_parse(&s, 1, passes2), PM_OK);
    assert_true(s.progressive);
    pm_settings_init(&s);
    assert_int_equal(pm_settings_parse(&s, 1, time), PM_OK);
    assert_true(s.progressive);
    assert_int_equal(pm_param_find("TARGET_ERROR"), PM_P_TARGET_ERROR);
    assert_int_equal(pm_param_find("target_error"), PM_P_COUNT);
}

static void test_engine_command_line(void **state)
{
    (void)state;
    char *argv[] = {"/some/bin/simd-gather", "map.pm", "-q",     "--threads", "4",  "--stats",
                    "stats/x.json",          "-o",     "b c.pm", "--radius",  "0.5"};
    char *line;
    assert_int_equal(pm_prov_command_line(11, argv, &line), PM_OK);
    assert_string_equal(line, "simd-gather map.pm -o 'b c.pm' --radius 0.5");
    free(line);
}

/* A radiance file at dir/name recording command, scene and one INPUT (name, hash). */
static void write_buffer(const char *dir, const char *name, const char *command, const char *scene, const char *in,
                         uint64_t in_hash, double value)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    pm_table_t t;
    assert_int_equal(pm_table_alloc(&t, &pm_radiance_schema, 1u << PM_RADIANCE_RGB, 6), PM_OK);
    for (int i = 0; i < 18; i++)
        ((double *)t.col[PM_RADIANCE_RGB])[i] = value;
    pm_header_set(&t.hdr, "width", "3");
    pm_header_set(&t.hdr, "height", "2");
    pm_header_set(&t.hdr, "component", "direct");
    pm_header_set(&t.hdr, "SCENE", "%s", scene);
    if (in)
        pm_header_add_input(&t.hdr, in, in_hash);
    char *words[8];
    char buf[256];
    snprintf(buf, sizeof buf, "%s", command);
    int n = 0;
    for (char *w = strtok(buf, " "); w && n < 8; w = strtok(NULL, " "))
        words[n++] = w;
    assert_int_equal(pm_header_add_command(&t.hdr, n, words), PM_OK);
    assert_int_equal(pm_table_write(&t, path), PM_OK);
    pm_table_free(&t);
}

static void test_engine_provenance(void **state)
{
    (void)state;
    char dir[256];
    snprintf(dir, sizeof dir, "%s/engine", unit_tmpdir());
    mkdir(dir, 0777);
    const char *scene = "box xxh3:0000000000000001";
    write_buffer(dir, "in.pm", "tracer /a/shot1.json -o in.pm", scene, NULL, 0, 1.0);
    char p[600];
    snprintf(p, sizeof p, "%s/in.pm", dir);
    uint64_t in_hash;
    assert_int_equal(pm_prov_trailer(p, &in_hash), PM_OK);
    write_buffer(dir, "out.pm", "stage in.pm -o out.pm", scene, "in.pm", in_hash, 2.0);

    const char *cmd[] = {"stage in.pm -o out.pm"};
    pm_prov_want_t w = {.dir = dir, .name = "out.pm", .commands = cmd, .ncommands = 1, .scene = scene};
    pm_prov_t v;
    assert_int_equal(pm_prov_check(&w, &v), PM_OK);
    assert_int_equal(v.verdict, PM_PROV_OK);
    assert_int_equal(v.count, 6);
    /* another command, another scene */
    const char *other[] = {"stage in.pm -o out.pm --radius 2"};
    w.commands = other;
    assert_int_equal(pm_prov_check(&w, &v), PM_OK);
    assert_int_equal(v.verdict, PM_PROV_OTHER);
    assert_non_null(strstr(v.why, "command 'stage in.pm -o out.pm'"));
    w.commands = cmd;
    w.scene = "box xxh3:0000000000000002";
    assert_int_equal(pm_prov_check(&w, &v), PM_OK);
    assert_int_equal(v.verdict, PM_PROV_OTHER);
    w.scene = scene;
    /* the scene's path is no part of the identity when scene_arg is set */
    const char *shot2[] = {"tracer /b/shot2.json -o in.pm"};
    pm_prov_want_t wi = {.dir = dir, .name = "in.pm", .commands = shot2, .ncommands = 1, .scene = scene};
    assert_int_equal(pm_prov_check(&wi, &v), PM_OK);
    assert_int_equal(v.verdict, PM_PROV_OTHER);
    wi.scene_arg = 1;
    assert_int_equal(pm_prov_check(&wi, &v), PM_OK);
    assert_int_equal(v.verdict, PM_PROV_OK);
    const char *quoted[] = {"tracer '/b/it'\\''s here.json' -o in.pm"};
    wi.commands = quoted;
    assert_int_equal(pm_prov_check(&wi, &v), PM_OK);
    assert_int_equal(v.verdict, PM_PROV_OK);
    /* an input with other bytes */
    write_buffer(dir, "in.pm", "tracer /a/shot1.json -o in.pm", scene, NULL, 0, 3.0);
    assert_int_equal(pm_prov_check(&w, &v), PM_OK);
    assert_int_equal(v.verdict, PM_PROV_OTHER);
    assert_string_equal(v.input, "in.pm");
    /* corrupt: a flipped payload byte, then a cut */
    snprintf(p, sizeof p, "%s/out.pm", dir);
    struct stat sb;
    assert_int_equal(stat(p, &sb), 0);
    int fd = open(p, O_RDWR);
    assert_true(fd >= 0);
    char c;
    assert_int_equal(pread(fd, &c, 1, sb.st_size - 20), 1);
    c ^= 0x55;
    assert_int_equal(pwrite(fd, &c, 1, sb.st_size - 20), 1);
    close(fd);
    assert_int_equal(pm_prov_check(&w, &v), PM_OK);
    assert_int_equal(v.verdict, PM_PROV_CORRUPT);
    assert_string_equal(v.why, "checksum mismatch");
    assert_int_equal(truncate(p, sb.st_size - 30), 0);
    assert_int_equal(pm_prov_check(&w, &v), PM_OK);
    assert_int_equal(v.verdict, PM_PROV_CORRUPT);
    assert_non_null(strstr(v.why, "truncated"));
    unlink(p);
    assert_int_equal(pm_prov_check(&w, &v), PM_OK);
    assert_int_equal(v.verdict, PM_PROV_MISSING);
    snprintf(p, sizeof p, "%s/in.pm", dir);
    unlink(p);
}

static void test_engine_spawn(void **state)
{
    (void)state;
    char *argv[] = {"/bin/sh", "-c", "echo oops >&2; exit 3", NULL};
    pm_spawn_t sp = {.argv = argv, .stdin_fd = -1, .stdout_fd = -1, .capture_stderr = 1};
    pm_proc_status_t st;
    assert_int_equal(pm_proc_run(&sp, &st), PM_OK);
    assert_int_equal(st.exit_code, 3);
    assert_string_equal(st.err, "oops\n");
    assert_true(st.wall_s >= 0);
    pm_proc_status_free(&st);
    assert_int_equal(pm_proc_class(0), PM_OK);
    assert_int_equal(pm_proc_class(1), PM_ERR_INPUT);
    assert_int_equal(pm_proc_class(2), PM_ERR_USAGE);
    assert_int_equal(pm_proc_class(3), PM_ERR_IO);
    assert_int_equal(pm_proc_class(4), PM_ERR_INTERNAL);
    assert_int_equal(pm_proc_class(137), PM_ERR_IO);
    /* stdout through a pipe, in another directory */
    int fds[2];
    assert_int_equal(pm_proc_pipe(fds), PM_OK);
    char *pwd[] = {"/bin/sh", "-c", "pwd", NULL};
    pm_spawn_t sp2 = {.argv = pwd, .cwd = "/", .stdin_fd = -1, .stdout_fd = fds[1]};
    pm_proc_t *proc;
    assert_int_equal(pm_proc_spawn(&sp2, &proc), PM_OK);
    close(fds[1]);
    char buf[16] = "";
    assert_int_equal(read(fds[0], buf, sizeof buf - 1), 2);
    close(fds[0]);
    assert_int_equal(pm_proc_wait(proc, &st), PM_OK);
    assert_int_equal(st.exit_code, 0);
    assert_null(st.err);
    assert_string_equal(buf, "/\n");
    /* a program that is not there is named */
    char *none[] = {"/nonexistent/program", NULL};
    pm_spawn_t sp3 = {.argv = none, .stdin_fd = -1, .stdout_fd = -1};
    pm_result_t r = pm_proc_spawn(&sp3, &proc);
    assert_int_equal(r, PM_ERR_IO);
    assert_non_null(strstr(pm_error_message(), "'/nonexistent/program'"));
    /* a stage's --stats, read back */
    char sp5[300];
    snprintf(sp5, sizeof sp5, "%s/engine-stats.json", unit_tmpdir());
    char *stats[] = {"/bin/sh", "-c", "printf '{\"stage\": \"x\", \"wall_s\": 0.5}' >\"$0\"", sp5, NULL};
    pm_spawn_t sp6 = {.argv = stats, .stdin_fd = -1, .stdout_fd = -1};
    assert_int_equal(pm_proc_run(&sp6, &st), PM_OK);
    assert_int_equal(st.exit_code, 0);
    json_t *j;
    assert_int_equal(pm_proc_stats_load(sp5, &j), PM_OK);
    assert_true(json_real_value(json_object_get(j, "wall_s")) == 0.5);
    json_decref(j);
    unlink(sp5);
    assert_int_equal(pm_proc_stats_load(sp5, &j), PM_ERR_INPUT);
    /* a killed one: 128 + the signal */
    char *killed[] = {"/bin/sh", "-c", "kill -9 $$", NULL};
    pm_spawn_t sp4 = {.argv = killed, .stdin_fd = -1, .stdout_fd = -1};
    assert_int_equal(pm_proc_run(&sp4, &st), PM_OK);
    assert_int_equal(st.signal, 9);
    assert_int_equal(st.exit_code, 137);
}

static const struct CMUnitTest tests[] = {
    cmocka_unit_test(test_engine_settings),
    cmocka_unit_test(test_engine_command_line),
    cmocka_unit_test(test_engine_provenance),
    cmocka_unit_test(test_engine_spawn),
};
UNIT_GROUP(unit_engine, "engine", tests);
