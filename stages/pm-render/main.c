/* pm-render: the render driver, an executive over the stage programs in the manner of
 * Radiance's rad: VAR=value settings, a table of stages, and a cache decided by provenance
 * alone (docs/programs/pm-render.md; pipelines/render is this program under another name).
 *
 *   pm-render SCENE OUTDIR [NAME=VALUE ...] [TARGET ...]
 *
 * Runs trace-photons, build-photonmap, trace-gather-points, hilbert-sort, the gather and
 * composite as programs (posix_spawn) in OUTDIR, keeps every intermediate there, and on a rerun
 * remakes only the files whose headers do not record what these settings would make
 * (common/engine). Progressive passes (PASSES > 1, TIME, TARGET_ERROR, PASS_RANGE) run through
 * resident stages (common/engine/progressive.c) when those handle the settings, else as pass
 * files, OUTDIR/pass-NNNN (common/engine/fixed.c, pm_render_passes). --check-settings judges
 * the settings alone. */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/memory.h"
#include "base/stage.h"
#include "engine/engine.h"
#include "engine/progressive.h"

static const char *const param_help =
    "Parameters (NAME=VALUE; empty means the stage's default, which is the scene's render block;\n"
    "with progressive passes (PASSES other than 1, TIME or TARGET_ERROR) PHOTONS, PRIMARY, SPP and K\n"
    "not given take per-pass defaults measured in docs/accuracy.md: " PM_PROGRESSIVE_PHOTONS_TEXT
    ", " PM_PROGRESSIVE_PRIMARY_TEXT ", " PM_PROGRESSIVE_SPP_TEXT " and " PM_PROGRESSIVE_K_TEXT "; PHOTONS\n"
    "75000 and K 2 for a TIME below 2 s, which has no boundary correction):\n"
    "  PHOTONS=N        photon paths (trace-photons --photons)\n"
    "  MAP=auto         global|indirect photon map; auto: global (gather mode needs first-hit photons)\n"
    "  MODE=gather      gather (final gather at secondary hits) | direct-vis (the map seen directly)\n"
    "  SPP=N            secondary rays per pixel, a multiple of 4\n"
    "  WIDTH=N HEIGHT=N image size (default: the scene camera's)\n"
    "  PRIMARY=N        primary rays per pixel\n"
    "  LIGHT_SAMPLES=N  area-light (and sun and sky) samples per primary hit (0 when the scene has none)\n"
    "  SECONDARY_DIRECT=auto  1: the gather points sample the lights too (an area light beyond sqrt(A)), and\n"
    "                   the map lacks their first hits (gather mode); auto: 1 for TIME of 10 s or more,\n"
    "                   and for any progressive render of a scene with a sun or a sky\n"
    "  COVERAGE=auto    1: simd-gather --coverage SCENE, the density estimate's boundary correction (no\n"
    "                   darkening where a kernel overhangs an edge or a corner; WIDTHS=fixed); auto: 1\n"
    "                   for progressive renders but a TIME below 2 s\n"
    "  DIFFUSE_DEPTH=auto  0, 1 or 2: secondary paths bounce off that many Lambertian surfaces (a light\n"
    "                   sample of every light and one ray on at each) before they gather (trace-gather-\n"
    "                   points --diffuse-depth; MODE=gather); auto: 1 from progressive pass 32 on, but\n"
    "                   0 for a scene with mirrors, glass or portals, and for one render\n"
    "  DIFFUSE_FROM=P   the first pass that bounces (default 1; with DIFFUSE_DEPTH=auto 32): earlier\n"
    "                   passes gather at the secondary hits (docs/accuracy.md)\n"
    "  GUIDE=0|1        1: guide the secondary rays by the photons (trace-photons --direction, then\n"
    "                   trace-gather-points --guide; MODE=gather; one pass or resident passes)\n"
    "  ADAPTIVE=auto    1: resident passes from the 5th on give each pixel primary rays by the running\n"
    "                   image's relative error (OUTDIR/adaptive.pm; composite weighs each pixel by its\n"
    "                   rays); 0: uniform passes; auto: 1 for a TIME budget\n"
    "  OVERLAP=auto     1: resident passes overlap, the next traced while the last is sorted and\n"
    "                   gathered (an adaptive pass then takes the map of the image one pass older);\n"
    "                   0: one pass at a time; auto: 1 for a TIME budget\n"
    "  ORDER=auto       hilbert|morton|none query order; auto: hilbert for gather, none for direct-vis\n"
    "  LEAF=N|auto      hilbert-sort --leaf\n"
    "  RADIUS=R K=K KERNEL=uniform|epanechnikov WIDTHS=fixed|variable ISA=...   simd-gather options\n"
    "  WIDTH_K=K        with WIDTHS=variable: build-photonmap --width-k (default K, else 50)\n"
    "  SHARDS=N         split the gather into N --range shards that composite adds (default 1)\n"
    "  GATHER=simd-gather  the gather program (any program with simd-gather's command line; for\n"
    "                   knn-gather RADIUS is its --max-radius), or none: the direct light alone\n"
    "  EXPOSURE=EV TONE=srgb|filmic HALF=0|1   composite's preview exposure, tone curve, half EXR\n"
    "  AOV=albedo,normal,depth   denoiser layers in image.exr (composite --aov; one-pass renders only)\n"
    "  SEED=N           the tracers' --seed (trace-photons, trace-gather-points)\n"
    "  PASSES=N         progressive passes (default 1: one render)\n"
    "  TIME=SECONDS     progressive: passes while the time so far plus the longest pass fits\n"
    "  TARGET_ERROR=E   progressive: stop when the running image's estimated relative error is at most E\n"
    "  ALPHA=A          progressive: the radius schedule's alpha in (0, 1) (default 2/3)\n"
    "  PASS_RANGE=A:B   progressive: make passes A to B alone (pipelines/slurm's tasks)\n"
    "  THREADS=N        every stage's --threads (changes no output)\n"
    "  JOBS=N           stages that may run at once, each when what it reads is made (default 1)\n"
    "  VERBOSE=1        print each stage's command line, its notes, and why a file is remade\n"
    "  QUIET=1          no progress on a terminal\n"
    "  WAIT=1           another render holding OUTDIR: wait for it (1) or refuse, exit 1 (0)\n"
    "  KEEP=all         what OUTDIR keeps after a render that succeeded: all (the cache), buffers\n"
    "                   (the radiance buffers composite adds) or image (image.exr, image.png, stats.json)\n"
    "TARGETs are files of the graph (photonmap.pm, sorted.pm, direct.pm, ...): only those and what\n"
    "they need are made. Exit status: 0 ok, 1 bad input or a stage failed on it (or OUTDIR is held\n"
    "and WAIT=0), 2 bad usage, 3 I/O or out of memory, 4 internal.\n";

/* word as the lock file shows it: bare when safe, else in single quotes */
static void append_word(char *out, size_t cap, const char *w)
{
    size_t n = strlen(out);
    int safe = w[0] != '\0';
    for (const char *p = w; *p; p++)
        if (!(('a' <= *p && *p <= 'z') || ('A' <= *p && *p <= 'Z') || ('0' <= *p && *p <= '9') ||
              strchr("/._-=:,+@%", *p)))
            safe = 0;
    if (n && n + 1 < cap)
        out[n++] = ' ', out[n] = '\0';
    if (safe) {
        snprintf(out + n, cap - n, "%s", w);
        return;
    }
    if (n + 1 < cap)
        out[n++] = '\'', out[n] = '\0';
    for (const char *p = w; *p && n + 5 < cap; p++) {
        if (*p == '\'') {
            memcpy(out + n, "'\\''", 4);
            n += 4;
        } else {
            out[n++] = *p;
        }
        out[n] = '\0';
    }
    if (n + 1 < cap)
        out[n++] = '\'', out[n] = '\0';
}

/* The parsed command line, freed at exit whichever of main's many returns is taken (a leak
 * checker counts it otherwise, and under LeakSanitizer a leak turns the exit status into 1). */
static pm_stage_t *stage_at_exit;
static void free_stage_args(void)
{
    if (stage_at_exit)
        pm_args_free(&stage_at_exit->args);
}

int main(int argc, char **argv)
{
    double t0 = pm_time_wall(); /* TIME counts from here */
    /* malloc on huge pages, for this driver's scene load and every stage it starts: once re-
     * executed, TIME still counts from the first start */
    pm_memory_huge_malloc(argv, t0);
    t0 = pm_memory_started(t0);
    const char *base = strrchr(argv[0], '/');
    base = base ? base + 1 : argv[0];
    /* As pipelines/render (exec -a), messages start "render:" as that driver's always did. */
    const char *me = strcmp(base, "render") == 0 ? "render" : "pm-render";
    if (argc > 1 && (!strcmp(argv[1], "-h") || !strcmp(argv[1], "--help")) && !strcmp(me, "render")) {
        printf("usage: %s SCENE OUTDIR [NAME=VALUE ...] [TARGET ...]\n%s", argv[0], param_help);
        return 0;
    }
    if (argc < 3 && !strcmp(me, "render")) {
        fprintf(stderr, "usage: %s SCENE OUTDIR [NAME=VALUE ...] [TARGET ...] (try --help)\n", argv[0]);
        return 2;
    }
    /* --check-settings (first): judge the parameters as a render would, render nothing, exit 0
     * or 2 with the first bad one (pipelines/slurm asks before it submits anything) */
    int check_only = argc > 1 && strcmp(argv[1], "--check-settings") == 0;
    if (check_only) {
        argv[1] = argv[0];
        argv++;
        argc--;
    }
    static pm_stage_t st; /* static: free_stage_args runs after main has returned */
    pm_stage_defaults(&st);
    const pm_option_t opts[] = {PM_STAGE_COMMON_OPTIONS(st), {0}};
    const pm_cli_t cli = {.program = "pm-render",
                          .synopsis = "[--check-settings] [options] SCENE OUTDIR [NAME=VALUE ...] [TARGET ...]",
                          .summary = "render SCENE into OUTDIR through the stage programs, remaking only what the "
                                     "settings change (by provenance); --threads is THREADS, --seed SEED, -q QUIET=1",
                          .options = opts,
                          .min_args = 2,
                          .max_args = -1};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    stage_at_exit = &st;
    atexit(free_stage_args);
    if (rc >= 0) {
        if (st.help)
            fputs(param_help, stdout);
        return rc;
    }
    char **args = st.args.args;
    int nargs = st.args.nargs;
    pm_settings_t s;
    pm_settings_init(&s);
    s.scene = args[0];
    s.outdir = args[1];
    /* the common options stand for their parameters (given ones only; NAME=VALUE wins) */
    char threads[32] = "", seed[32] = "";
    if (st.args.given[1]) {
        snprintf(threads, sizeof threads, "%lld", (long long)st.threads);
        s.value[PM_P_THREADS] = threads;
    }
    if (st.args.given[2]) {
        snprintf(seed, sizeof seed, "%lld", (long long)st.seed);
        s.value[PM_P_SEED] = seed;
    }
    if (st.quiet)
        s.value[PM_P_QUIET] = "1";
    /* pipelines/render's order: the scene, then the parameters */
    if (access(s.scene, R_OK) != 0) {
        int e = errno;
        fprintf(stderr, "%s: cannot read scene '%s': %s\n", me, s.scene, strerror(e));
        return pm_result_exit_code(pm_result_of_errno(e));
    }
    if (strchr(s.scene, '\n') || strchr(s.outdir, '\n')) {
        fprintf(stderr, "%s: a scene path or OUTDIR cannot hold a newline\n", me);
        return 2;
    }
    if (pm_settings_parse(&s, nargs - 2, args + 2) != PM_OK) {
        fprintf(stderr, "%s: %s\n", me, pm_error_message());
        return 2;
    }
    char bin[PATH_MAX];
    if (pm_engine_bin(bin, sizeof bin) != PM_OK) {
        fprintf(stderr, "%s: %s\n", me, pm_error_message());
        return 2;
    }
    char cmdline[8192] = "";
    append_word(cmdline, sizeof cmdline, argv[0]);
    for (int i = 1; i < argc; i++)
        append_word(cmdline, sizeof cmdline, argv[i]);
    if (check_only) {
        if (pm_settings_check_stages(&s, bin) != PM_OK) {
            fprintf(stderr, "%s: %s\n", me, pm_error_message());
            return 2;
        }
        return 0;
    }
    if (s.progressive && pm_progressive_handles(&s, NULL, 0)) { /* resident passes: common/engine/progressive.c */
        if (pm_settings_check_stages(&s, bin) != PM_OK) {
            fprintf(stderr, "%s: %s\n", me, pm_error_message());
            return 2;
        }
        int status = pm_render_progressive(&s, me, bin, cmdline, t0);
        if (status >= 0)
            return status; /* else an OUTDIR of pass directories: the pass files below */
    }
    if (pm_settings_check_stages(&s, bin) != PM_OK) {
        fprintf(stderr, "%s: %s\n", me, pm_error_message());
        return 2;
    }
    if (s.progressive && !strcmp(s.value[PM_P_ADAPTIVE], "1")) { /* auto: the pass files are uniform */
        char why[128];
        pm_progressive_handles(&s, why, sizeof why);
        fprintf(stderr, "%s: ADAPTIVE=1 adapts the resident passes, which %s does not allow\n", me,
                why[0] ? why : "an OUTDIR of pass directories");
        return 2;
    }
    if (s.progressive) /* passes as files: common/engine/fixed.c */
        return pm_render_passes(&s, me, bin, cmdline, t0);
    return pm_render_fixed(&s, me, bin, cmdline);
}
