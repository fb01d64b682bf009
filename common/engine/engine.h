/* engine.h: the render driver's library (bin/pm-render, docs/programs/pm-render.md): its
 * settings, its table of stages, how it starts a stage, and how it decides by provenance
 * whether an intermediate is what the current settings would make.
 *
 * The engine sits above every other layer: it loads the scene through common/render (what the
 * scene holds and needs) and reads intermediates through formats, but it never traces, sorts
 * or gathers itself. Each stage stays a program a user can run alone; the engine starts it
 * with posix_spawn, with pipes where one stage feeds the next, and judges each file by its
 * header (COMMAND lines, INPUT content hashes, the SCENE parts) and its checksum trailer. No
 * dates, stamp files, seals or make: docs/pipelines.md, "How reuse is decided".
 *
 * Like the rest of the library it never exits and returns pm_result_t; only pm-render's main
 * picks the exit status. */
#ifndef PM_ENGINE_H
#define PM_ENGINE_H

#include <jansson.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "base/error.h"
#include "render/scene_cache.h"

/* ---- settings: pipelines/render's NAME=VALUE parameters ---- */

/* Every parameter pipelines/render takes, in the order --help lists them. */
typedef enum {
    PM_P_PHOTONS,
    PM_P_MAP,
    PM_P_MODE,
    PM_P_SPP,
    PM_P_WIDTH,
    PM_P_HEIGHT,
    PM_P_PRIMARY,
    PM_P_LIGHT_SAMPLES,
    PM_P_GUIDE,
    PM_P_ORDER,
    PM_P_LEAF,
    PM_P_RADIUS,
    PM_P_K,
    PM_P_KERNEL,
    PM_P_WIDTHS,
    PM_P_ISA,
    PM_P_WIDTH_K,
    PM_P_SHARDS,
    PM_P_GATHER,
    PM_P_EXPOSURE,
    PM_P_TONE,
    PM_P_HALF,
    PM_P_AOV,
    PM_P_SEED,
    PM_P_PASSES,
    PM_P_TIME,
    PM_P_TARGET_ERROR,
    PM_P_ALPHA,
    PM_P_PASS_RANGE,
    PM_P_THREADS,
    PM_P_JOBS,
    PM_P_VERBOSE,
    PM_P_QUIET,
    PM_P_WAIT,
    PM_P_KEEP,
    PM_P_SECONDARY_DIRECT,
    PM_P_COVERAGE,
    PM_P_ADAPTIVE,
    PM_P_DIFFUSE_DEPTH,
    PM_P_DIFFUSE_FROM,
    PM_P_OVERLAP,
    PM_P_COUNT
} pm_param_t;

/* A parameter's name ("PHOTONS") and its default as text ("" means the stage's own default,
 * which is the scene's render block). */
const char *pm_param_name(pm_param_t p);
const char *pm_param_default(pm_param_t p);
/* The parameter called name, or PM_P_COUNT when there is none. */
pm_param_t pm_param_find(const char *name);

#define PM_ENGINE_MAX_TARGETS 64

/* What one pm-render command line asks for. Values are the text given (or the default), as
 * pipelines/render kept them; the derived fields below are filled by pm_settings_parse from
 * them, after the checks that need no program (choices, counts, numbers). */
typedef struct {
    const char *scene;  /* the scene file as given */
    const char *outdir; /* OUTDIR as given */
    const char *value[PM_P_COUNT];
    const char *targets[PM_ENGINE_MAX_TARGETS]; /* files of the graph to make, in order */
    int ntargets;
    /* derived */
    int progressive;          /* PASSES > 1, TIME, TARGET_ERROR or PASS_RANGE */
    unsigned aov;             /* AOV: the PM_EXR_AOV_* layers composite adds (base/exr.h); 0 none */
    int shards;               /* SHARDS, >= 1 */
    int verbose, quiet;       /* VERBOSE=1, QUIET=1 */
    int wait;                 /* WAIT=1 */
    int keep;                 /* 0 all, 1 buffers, 2 image (KEEP) */
    int guide;                /* GUIDE=1: trace-gather-points --guide photons.pm (one-pass gather renders) */
    int secondary_direct;     /* SECONDARY_DIRECT=1 with MODE=gather: light samples at the gather points
                               * (trace-gather-points --secondary-direct) and photons without the first
                               * hits of the lights they sample (trace-photons --indirect-only) */
    int secondary_direct_sky; /* SECONDARY_DIRECT=auto on a progressive render that it does not turn on by
                               * TIME: on when the scene has a sun or a sky (the drivers decide, with the scene) */
    int diffuse_depth;        /* DIFFUSE_DEPTH (0, 1 or 2; MODE=gather), auto's resolved: trace-gather-points
                               * --diffuse-depth; 0 none */
    int diffuse_from;         /* the first pass that takes them (DIFFUSE_FROM; auto: PM_DIFFUSE_AUTO_FROM):
                               * trace-gather-points --diffuse-from when above 1 */
    int diffuse_auto;         /* DIFFUSE_DEPTH=auto: the drivers turn it off for a scene with mirrors or
                               * glass, or with portals (pm_diffuse_depth_for) */
    int coverage;             /* COVERAGE=1, or auto on a progressive render (TIME from 2 s): simd-gather --coverage
                               * SCENE, the density estimate's boundary correction */
    int adaptive;             /* ADAPTIVE=1, or auto on a progressive render: the resident passes from
                               * PM_ADAPTIVE_FROM_PASS on give each pixel rays by the running image's error
                               * (common/engine/progressive.c, image/adaptive.h) */
    int overlap;              /* OVERLAP=1, or auto on a TIME budget: the resident driver plans and traces a
                               * pass while the one before it is still sorted and gathered */
} pm_settings_t;

enum { PM_KEEP_ALL = 0, PM_KEEP_BUFFERS = 1, PM_KEEP_IMAGE = 2 };

/* DIFFUSE_DEPTH=auto: the pass from which a progressive render's secondary paths bounce once
 * before they gather (docs/accuracy.md, "A diffuse bounce from a later pass on"). A pass
 * number, not a time: the map's radius and each pixel's samples after n passes do not depend
 * on the image's size or the machine, so neither does where the bounce starts to pay. */
#define PM_DIFFUSE_AUTO_FROM 32

/* The Lambertian bounces before the gather a render of a scene with these takes: s->diffuse_depth,
 * but 0 under DIFFUSE_DEPTH=auto for a scene with mirrors or glass (specular: a bounce's path on
 * through them to a light is a caustic path traced from the eye, the noise the caustic map is
 * there to avoid) or with portals (the light comes in through small openings, which a light
 * sample at the bounce rarely finds); both measured worse with the bounce (docs/accuracy.md). */
int pm_diffuse_depth_for(const pm_settings_t *s, int specular, int portals);

/* K, the photons r_1 is measured to hold on pass 1's queries, when not given, for progressive
 * passes: "2" for a TIME budget too short for the boundary correction (COVERAGE=auto off below
 * 2 s), whose kernel then darkens every edge it overhangs and is better small (the atria's
 * TIME=1 relMSE 10 to 14% lower, the Cornell box's the same); "5" otherwise (docs/accuracy.md,
 * "Progressive defaults" and "The boundary correction from 2 s"). */
const char *pm_progressive_default_k(const pm_settings_t *s);
/* PHOTONS, the photon paths of a full progressive pass, when not given: "75000" for the same
 * short budgets as K 2 (below 2 s), whose error is the eye side's noise, so that the photons'
 * tracing and tree go to rays instead (at TIME=1, 128 x 128, ten runs each: the Cornell box's
 * relMSE 0.00052 to 0.00092 against 0.0011 to 0.0016; the sky-lit atrium 0.90 and the skylight
 * room 0.82 times, the atrium 1.04 and the caustic scene 1.08 times, three runs each); "300000"
 * otherwise (docs/accuracy.md, "Fewer photons at 1 s"). */
const char *pm_progressive_default_photons(const pm_settings_t *s);
/* The per-pass defaults of progressive passes from 2 s on (docs/accuracy.md, "Progressive
 * defaults"), as numbers and as their texts, for both drivers (progressive.c, fixed.c), the
 * settings' defaults above and pm-render's help: PHOTONS a full pass (pm_progressive_default_photons
 * from 2 s), PRIMARY and SPP, K (pm_progressive_default_k from 2 s). */
#define PM_PROGRESSIVE_PHOTONS 300000
#define PM_PROGRESSIVE_PRIMARY 16
#define PM_PROGRESSIVE_SPP 4
#define PM_PROGRESSIVE_K 5
#define PM_PROGRESSIVE_TEXT_(x) #x
#define PM_PROGRESSIVE_TEXT(x) PM_PROGRESSIVE_TEXT_(x)
#define PM_PROGRESSIVE_PHOTONS_TEXT PM_PROGRESSIVE_TEXT(PM_PROGRESSIVE_PHOTONS)
#define PM_PROGRESSIVE_PRIMARY_TEXT PM_PROGRESSIVE_TEXT(PM_PROGRESSIVE_PRIMARY)
#define PM_PROGRESSIVE_SPP_TEXT PM_PROGRESSIVE_TEXT(PM_PROGRESSIVE_SPP)
#define PM_PROGRESSIVE_K_TEXT PM_PROGRESSIVE_TEXT(PM_PROGRESSIVE_K)

/* Fills s with the defaults. */
void pm_settings_init(pm_settings_t *s);
/* Parses pm-render's arguments after SCENE and OUTDIR: NAME=VALUE words and TARGET words
 * (pointers into argv are kept). PM_ERR_USAGE with a one-line message ("unknown parameter
 * 'X' (known: ...)", "bad value for SHARDS '0': expected a count of at least 1") on the
 * first bad one; the values the stages judge themselves (PHOTONS, RADIUS, ...) are left to
 * pm_settings_check_stages. */
pm_result_t pm_settings_parse(pm_settings_t *s, int argc, char **argv);
/* Asks each stage to judge the values it reads (PROGRAM --option VALUE --print-settings, which
 * parses and exits without reading input): PM_ERR_USAGE with "bad value for NAME 'V': the
 * stage's message" on the first it refuses. bin is the program directory. */
pm_result_t pm_settings_check_stages(const pm_settings_t *s, const char *bin);

/* ---- spawn: a stage as a process ---- */

/* How to start one program. */
typedef struct {
    char *const *argv;    /* argv[0] is the program's path; NULL-terminated */
    const char *cwd;      /* directory to run in; NULL: the driver's */
    int stdin_fd;         /* fd to give the program as stdin; -1: the driver's */
    int stdout_fd;        /* fd to give it as stdout; -1: the driver's */
    int capture_stderr;   /* 1: its stderr into pm_proc_status_t.err; 0: passed through */
    const int *close_fds; /* fds the child must not inherit (the other ends of its pipes), */
    int nclose;           /* so that a reader sees end of file when its writer exits */
    char *const *env;     /* environment; NULL: the driver's */
    int extra_fd;         /* with extra_to > 2: an fd to give the program as extra_to as well */
    int extra_to;         /* (pipelines/frames' --direct /dev/fd/3); 0: none */
} pm_spawn_t;

/* How a program ended. */
typedef struct {
    int exit_code; /* its exit status; 128 + signal when a signal ended it */
    int signal;    /* the signal that ended it, 0 if none */
    double wall_s; /* s (wall) from spawn to exit */
    char *err;     /* its stderr when captured (malloc'd, NUL-terminated, may be ""), else NULL */
} pm_proc_status_t;

typedef struct pm_proc pm_proc_t;

/* Starts the program; *out is its handle, to be waited for with pm_proc_wait. PM_ERR_IO
 * when posix_spawn fails (a missing or non-executable program is named). */
pm_result_t pm_proc_spawn(const pm_spawn_t *sp, pm_proc_t **out);
/* Waits for it to end and frees the handle; *status_out says how it ended (its err is the
 * caller's to free with pm_proc_status_free). */
pm_result_t pm_proc_wait(pm_proc_t *p, pm_proc_status_t *status_out);
void pm_proc_status_free(pm_proc_status_t *st);
/* Waits for whichever of procs[0..n) (NULL entries skipped) ends first: *which_out is its index,
 * its handle freed (the caller sets procs[*which_out] to NULL). For programs whose stderr is
 * passed through: a captured one is read only once the program has ended. */
pm_result_t pm_proc_wait_any(pm_proc_t *const *procs, int n, int *which_out, pm_proc_status_t *status_out);
/* The CPU seconds (user and system, every thread) the running program has used so far, from
 * /proc/PID/stat; -1 when they cannot be read (a program that has ended and been waited for). A
 * resident stage's use between two readings is its compute in that span: one blocked on a pipe
 * uses none. */
double pm_proc_cpu_s(const pm_proc_t *p);
/* Sends signal sig to the running program (not yet waited for). */
void pm_proc_signal(const pm_proc_t *p, int sig);
/* The program directory the drivers start the stages from: BIN in the environment when set
 * (absolute; PM_ERR_USAGE "no program directory 'X'" when it is none), else the directory of
 * the running program. */
pm_result_t pm_engine_bin(char *out, size_t cap);
/* A driver's line on stderr: "ME: message" (its progress, notes and errors; never under
 * QUIET's control: the callers decide). */
void pm_engine_say(const char *me, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Runs one program to its end (pm_proc_spawn then pm_proc_wait). */
pm_result_t pm_proc_run(const pm_spawn_t *sp, pm_proc_status_t *status_out);
/* A stage's --stats file as JSON (*j_out the caller's to json_decref); PM_ERR_INPUT when it is
 * missing or not JSON. */
pm_result_t pm_proc_stats_load(const char *path, json_t **j_out);
/* A pipe whose two ends close on exec (each child gets the end it needs as stdin or stdout). */
pm_result_t pm_proc_pipe(int fds_out[2]);
/* The error class (PM_ERR_*) a stage's exit status stands for (docs/cli.md): 1 input, 2
 * usage, 3 io or out of memory, 4 internal; a signal is io. PM_OK for 0. */
pm_result_t pm_proc_class(int exit_code);

/* ---- provenance: is this intermediate what the current settings would make? ---- */

/* What a file must record to be kept. */
typedef struct {
    const char *dir;             /* the directory the file and its INPUT paths are in */
    const char *name;            /* the file, relative to dir */
    const char *const *commands; /* the COMMAND lines its header must end with, oldest first, */
    size_t ncommands;            /* as pm_prov_command_line makes them */
    const char *scene;           /* the SCENE value it must record; NULL: not checked */
    int external;                /* 1: made by a program outside the program directory (GATHER=PATH),
                                  * maybe a wrapper of another: its own COMMAND line is compared
                                  * without the program's name (a program that records none is remade) */
    int scene_arg;               /* 1: the word after the program's name in its own command line is
                                  * the scene file, which SCENE judges by content: its path is no part
                                  * of the identity (shot2.json with shot1.json's photon part) */
} pm_prov_want_t;

typedef enum {
    PM_PROV_OK,      /* whole, and made as the settings would make it: keep it */
    PM_PROV_MISSING, /* not there */
    PM_PROV_CORRUPT, /* not a whole pmtk file: checksum, truncation, format (why says) */
    PM_PROV_OTHER    /* whole, but made otherwise: another command, scene or input (why says) */
} pm_prov_verdict_t;

/* What pm_prov_check found. */
typedef struct {
    pm_prov_verdict_t verdict;
    uint64_t hash;   /* the file's content hash (its XXH3 trailer) when whole */
    uint64_t count;  /* its records, when whole */
    char why[512];   /* for CORRUPT and OTHER: "checksum mismatch", "command 'simd-gather ...'" */
    char input[256]; /* for OTHER because of an input: that input's name as the header records it */
} pm_prov_t;

/* Reads dir/name's header with the formats library, checks that the file is whole (its size
 * is the header's, its XXH3 trailer the hash of every byte before it; the records' values are
 * the reading stage's to check) and compares its provenance with w: the SCENE key, the last ncommands COMMAND lines,
 * and each INPUT's content hash against the file of that name in dir as it is now (an input that is missing or a pipe,
 * "-", is not compared: what makes it is judged on its own). Returns an error only when the check itself cannot run
 * (out of memory); every verdict is PM_OK. */
pm_result_t pm_prov_check(const pm_prov_want_t *w, pm_prov_t *out);
/* The content hash of a pmtk file: its last 8 bytes (little-endian XXH3-64), not checked.
 * PM_ERR_IO when it cannot be read or is shorter than 8 bytes. */
pm_result_t pm_prov_trailer(const char *path, uint64_t *hash_out);
/* The COMMAND line a stage run as argv (argc words) records: argv[0] reduced to its base
 * name, without -q/--quiet, --threads N and --stats FILE (which change no output and which
 * the stages leave out), quoted as pm_header_add_command quotes. *out_line is malloc'd. */
pm_result_t pm_prov_command_line(int argc, char *const *argv, char **line_out);

/* ---- the stage table ---- */

/* One program of the chain as the engine knows it. */
typedef struct {
    const char *name;    /* its row in the time table and its stats/NAME.json: "trace-photons" */
    const char *program; /* the binary in the program directory */
    int scene_part;      /* the SCENE part its outputs record: 0 all, 1 photons, 2 view */
} pm_stage_info_t;

/* The stages of the fixed chain, in the order they run and the time table lists them:
 * trace-photons, build-photonmap, build-photonmap.caustic, trace-gather-points, hilbert-sort,
 * simd-gather (the gather; its name is the gather program's), simd-gather.caustic, composite. */
const pm_stage_info_t *pm_stage_table(size_t *n_out);

/* ---- one render ---- */

/* The scene cache of a render in outdir (render/scene_cache.h), the driver's and its stages':
 * the environment's PMTK_SCENE_CACHE when it is set (empty: none), else OUTDIR/scene.cache.
 * Written into out (cap bytes); returns out. spawn.c. */
const char *pm_engine_scene_cache(const char *outdir, char *out, size_t cap);
/* A driver's scene, before OUTDIR's lock: from the cache (pm_engine_scene_cache of outdir, into
 * cache) when it holds it, else loaded from its files and written by pm_engine_scene_keep once the
 * lock is the driver's, so that a render the lock refuses leaves the cache as it was. */
pm_result_t pm_engine_scene_load(const char *outdir, const char *scene, char *cache, size_t cap, pm_scene_t *sc,
                                 pm_scene_cache_status_t *st);
/* After the lock: a miss written to cache (the scene's file when it names a directory), and
 * VERBOSE's line. */
void pm_engine_scene_keep(const char *me, int verbose, const char *cache, const pm_scene_t *sc,
                          pm_scene_cache_status_t *st);
/* VERBOSE's line on stderr of what the driver's load did with the cache: "me: scene cache PATH:
 * read", "written (it was absent)", "not written (why)", "not used (...)". */
void pm_engine_say_scene_cache(const char *me, const char *cache, const pm_scene_cache_status_t *st, int uncacheable);

/* One render at a time in OUTDIR: takes an exclusive flock on OUTDIR/.lock (kept in *fd_out and
 * inherited by the stages) and writes "pid N: cmdline" into it, so that a second render names the holder.
 * With wait 0 a held OUTDIR is refused at once, else waited for (with a message). Messages
 * start with "me: ". Returns the exit status: 0 locked, 1 held with wait 0 (or a path that
 * cannot be, by its errno), 3 when the system fails (base/error.h's classes). */
int pm_engine_lock(const char *me, const char *outdir, int wait, const char *cmdline, int *fd_out);

/* One render of the whole chain (no passes) into s->outdir, as pipelines/render did: the lock,
 * the scene loaded through the library, the graph, each intermediate judged by provenance and
 * remade when it is not what s would make (and what reads it, when its bytes changed), the
 * time table on stdout, stats.json, KEEP. Messages start with "me: ". bin is the program
 * directory (absolute); cmdline is what the lock file records. Returns the exit status: 0 ok,
 * 1 bad input (or OUTDIR held with WAIT=0), 2 usage, 3 I/O or out of memory, 4 internal (a
 * stage's class passed through). */
int pm_render_fixed(const pm_settings_t *s, const char *me, const char *bin, const char *cmdline);

/* A progressive render whose passes are kept as files, OUTDIR/pass-NNNN/ (KEEP=all given,
 * PASS_RANGE for pipelines/slurm's tasks, and what the resident passes do not run: MODE=direct-vis,
 * SHARDS, another GATHER, ORDER=none, the caustic branch): each pass the chain with --pass, judged
 * by provenance as one render is, its buffers added by composite --accumulate to OUTDIR/running.pm
 * and the images, OUTDIR/passes.txt listing the passes in it. PASS_RANGE=A:B makes passes A to B
 * alone (stopped at the TARGETs: gather-inputs, indirect.I.pm) and says "pass P made (STAGES)" on
 * stdout for each. t0 is when the command started (TIME counts from it). Returns the exit status
 * as pm_render_fixed does. */
int pm_render_passes(const pm_settings_t *s, const char *me, const char *bin, const char *cmdline, double t0);

/* pipelines/frames (bin/pm-frames): a camera or point-light path as frames, SCENE's scene file per
 * frame in OUTDIR, the stages resident on streams of documents (STREAM=1) or run per frame, the
 * NAME=VALUE parameters argv[0..argc) judged first (exit 2), OUTDIR held by pm_engine_lock for the
 * run (a second run is refused, exit 1). Messages start with "me: "; bin is the program
 * directory; cmdline is what the lock file records. Returns the exit status (docs/cli.md). */
int pm_frames_run(const char *me, const char *scene, const char *outdir, int argc, char **argv, const char *bin,
                  const char *cmdline);

#endif
