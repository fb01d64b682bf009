/* frames.c: a camera (or point-light) path rendered as a sequence of frames, as in the paper's
 * interactive session (bin/pm-frames, which pipelines/frames is; docs/pipelines.md, "Frames").
 *
 * Each frame gets its own scene file (OUTDIR/scene-NNNN.json: the scene with the camera eye, or
 * every point light, moved along the path, mesh paths made absolute). With STREAM=1 the stages
 * are resident, each taking a stream of documents, one per frame, started through the engine's
 * spawn with pipes between them:
 *
 *   MOVE=camera: trace-photons scene-0000.json | build-photonmap -o map.pm, then
 *     trace-gather-points scene-*.json -o - --direct /dev/fd/3 (3: direct.fifo) | hilbert-sort
 *       --stream | simd-gather --stream queries map.pm - | composite --stream direct.fifo -
 *   MOVE=light: trace-gather-points scene-0000.json | hilbert-sort > sorted.pm, then
 *     trace-gather-points --no-queries scene-*.json --direct /dev/fd/3 (beside) and
 *     trace-photons scene-*.json | build-photonmap --stream | simd-gather --stream map - sorted.pm
 *       | composite --stream direct.fifo -
 *
 * STREAM=0 (and REUSE=0) runs every stage once per frame with files between them. Both give the
 * same frames, byte for byte. OUTDIR is held by the engine's lock (OUTDIR/.lock) for the run. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "base/args.h"
#include "base/timer.h"
#include "engine/engine.h"
#include "render/light.h"
#include "render/scene.h"

typedef enum {
    F_FRAMES,
    F_MOVE,
    F_DEGREES,
    F_SHIFT,
    F_PHOTONS,
    F_SPP,
    F_WIDTH,
    F_HEIGHT,
    F_RADIUS,
    F_K,
    F_PRIMARY,
    F_PIXEL,
    F_ORDER,
    F_THREADS,
    F_PNG,
    F_OVERLAP,
    F_MODE,
    F_REUSE,
    F_QUIET,
    F_STREAM,
    F_SECONDARY_DIRECT,
    F_DIFFUSE_DEPTH,
    F_COUNT
} fparam_t;

static const char *const fnames[F_COUNT] = {
    "FRAMES",       "MOVE",    "DEGREES", "SHIFT",   "PHOTONS", "SPP",    "WIDTH",
    "HEIGHT",       "RADIUS",  "K",       "PRIMARY", "PIXEL",   "ORDER",  "THREADS",
    "PNG",          "OVERLAP", "MODE",    "REUSE",   "QUIET",   "STREAM", "SECONDARY_DIRECT",
    "DIFFUSE_DEPTH"};
static const char *const fdefaults[F_COUNT] = {"8", "camera",  "30", "0.1", "",  "",       "",  "",  "",  "",  "",
                                               "",  "hilbert", "",   "1",   "1", "gather", "1", "0", "1", "0", "0"};

#define MAXF 100000
#define MAXA 48

typedef struct {
    const char *me, *scene_arg, *bin;
    char out[PATH_MAX], scene_dir[PATH_MAX];
    const char *v[F_COUNT];
    int n, camera, direct, png, stream, progress;
    int sec_direct; /* SECONDARY_DIRECT=1 on a scene with lights the gather points sample */
    double t0, t_map;
    char radius[64]; /* STREAM=0: frame 0's kernel width, for the later frames */
} frames_t;

/* the driver's lines on stderr, "ME: ..." (pm_engine_say) */
#define fsay(F, ...) pm_engine_say((F)->me, __VA_ARGS__)

/* A command line being built: argv words owned here. */
typedef struct {
    char *a[MAXA + 1];
    int n;
} cmd_t;

static void add(cmd_t *c, const char *w)
{
    if (c->n < MAXA)
        c->a[c->n++] = strdup(w);
    c->a[c->n] = NULL;
}
static void opt(cmd_t *c, const char *flag, const char *v)
{
    if (v && v[0]) {
        add(c, flag);
        add(c, v);
    }
}
static void prog(const frames_t *F, cmd_t *c, const char *name)
{
    char p[PATH_MAX + 64];
    snprintf(p, sizeof p, "%s/%s", F->bin, name);
    add(c, p);
    add(c, "-q");
}
static void cmd_free(cmd_t *c)
{
    for (int i = 0; i < c->n; i++)
        free(c->a[i]);
    c->n = 0;
}
static void threads(const frames_t *F, cmd_t *c) { opt(c, "--threads", F->v[F_THREADS]); }
static void stats(const frames_t *F, cmd_t *c, const char *name)
{
    char p[PATH_MAX + 96];
    snprintf(p, sizeof p, "%s/stats/%s.json", F->out, name);
    add(c, "--stats");
    add(c, p);
}
/* trace-gather-points' eye options (SPP ... PIXEL, MODE) */
static void eye_opts(const frames_t *F, cmd_t *c)
{
    opt(c, "--spp", F->v[F_SPP]);
    opt(c, "--width", F->v[F_WIDTH]);
    opt(c, "--height", F->v[F_HEIGHT]);
    opt(c, "--primary", F->v[F_PRIMARY]);
    opt(c, "--pixel", F->v[F_PIXEL]);
    if (!strcmp(F->v[F_MODE], "direct-vis")) {
        add(c, "--mode");
        add(c, "direct-vis");
    }
    if (F->sec_direct) /* every eye stage's: the queries' header must say it to the gather too */
        add(c, "--secondary-direct");
    if (strcmp(F->v[F_DIFFUSE_DEPTH], "0") != 0)
        opt(c, "--diffuse-depth", F->v[F_DIFFUSE_DEPTH]);
}
/* trace-photons' options beside its scene: --photons, and with secondary direct light the map
 * without the first hits the gather points' light samples stand for */
static void photon_opts(const frames_t *F, cmd_t *c)
{
    opt(c, "--photons", F->v[F_PHOTONS]);
    if (F->sec_direct)
        add(c, "--indirect-only");
}
/* hilbert-sort on a stream of documents, stdin to stdout */
static void sort_stream(const frames_t *F, cmd_t *h)
{
    prog(F, h, "hilbert-sort");
    add(h, "--stream");
    add(h, "-");
    add(h, "--order");
    add(h, F->v[F_ORDER]);
    threads(F, h);
    add(h, "-o");
    add(h, "-");
    stats(F, h, "hilbert-sort");
}
/* simd-gather on a stream: of queries against map (a file), or of maps against queries */
static void gather_stream(const frames_t *F, cmd_t *g, const char *stream, const char *a, const char *b)
{
    prog(F, g, "simd-gather");
    add(g, "--stream");
    add(g, stream);
    opt(g, "--radius", F->v[F_RADIUS]);
    opt(g, "--k", F->v[F_K]);
    threads(F, g);
    add(g, a);
    add(g, b);
    add(g, "-o");
    add(g, "-");
    stats(F, g, "simd-gather");
}

static void scene_path(const frames_t *F, int f, char *out, size_t cap)
{
    snprintf(out, cap, "%s/scene-%04d.json", F->out, f);
}
static void scenes(const frames_t *F, cmd_t *c)
{
    char p[PATH_MAX + 32];
    for (int f = 0; f < F->n; f++) {
        scene_path(F, f, p, sizeof p);
        add(c, p);
    }
}

/* The class of a set of stage statuses: 4 (a bug) before 3 (the system) before 1; 0 when all are
 * 0. Any other status, a signal's too, is 1: in a pipe the stages after a failing one die of
 * the short stream (SIGPIPE), which is not what counts. */
static int worst(const int *codes, int n)
{
    int w = 0;
    for (int i = 0; i < n; i++) {
        int c = codes[i];
        if (c == 0)
            continue;
        if (c == 4)
            w = 4;
        else if (c == 3 && w != 4)
            w = 3;
        else if (w == 0)
            w = 1;
    }
    return w;
}

/* ---- the processes of a run: started with pipes, waited for together ---- */

typedef struct {
    pm_proc_t *p[12];
    int code[12];
    int n;
    int fifo_rd; /* the driver's read end of direct.fifo, closed once composite ends */
    int composite;
    int failed; /* a stage has failed: the others were sent SIGTERM */
} run_t;

static int start(const frames_t *F, run_t *R, cmd_t *c, int in, int out, int fd3)
{
    pm_spawn_t sp = {.argv = c->a, .stdin_fd = in, .stdout_fd = out, .extra_fd = fd3, .extra_to = fd3 >= 0 ? 3 : 0};
    int i = R->n++;
    R->code[i] = 0;
    if (pm_proc_spawn(&sp, &R->p[i]) != PM_OK) {
        fsay(F, "%s", pm_error_message());
        R->p[i] = NULL;
        R->code[i] = 3;
    }
    return i;
}

/* Waits for every process of R; when composite ends, the driver's end of the FIFO is closed, so
 * that a writer whose reader is gone fails instead of waiting. */
static int wait_range(const frames_t *F, run_t *R, int a, int b)
{
    for (;;) {
        int live = 0;
        for (int i = a; i < b; i++)
            live += R->p[i] != NULL;
        if (!live)
            break;
        int which;
        pm_proc_status_t st;
        if (pm_proc_wait_any(R->p, R->n, &which, &st) != PM_OK) {
            fsay(F, "%s", pm_error_message());
            return 4;
        }
        R->p[which] = NULL;
        R->code[which] = st.exit_code;
        pm_proc_status_free(&st);
        /* One stage failed: the run has failed, and the others are ended rather than waited for
         * (one may never end: composite waits in its open of direct.fifo, by name, for a writer
         * that died before it got there). Their statuses (a signal) never outrank the failure's
         * class (worst). */
        if (R->code[which] != 0 && !R->failed) {
            R->failed = 1;
            for (int i = 0; i < R->n; i++)
                if (R->p[i] && i != which)
                    pm_proc_signal(R->p[i], SIGTERM);
        }
        if (which == R->composite && R->fifo_rd >= 0) {
            close(R->fifo_rd);
            R->fifo_rd = -1;
        }
    }
    return worst(R->code + a, b - a);
}

/* Waits for processes [a, b) of R (the others of R that end meanwhile are recorded too: one
 * wait serves every process the driver started); the class of their statuses. */
static int wait_all(const frames_t *F, run_t *R) { return wait_range(F, R, 0, R->n); }

static int pipe_or_say(const frames_t *F, int fds[2])
{
    if (pm_proc_pipe(fds) != PM_OK) {
        fsay(F, "%s", pm_error_message());
        return 3;
    }
    return 0;
}

/* direct.fifo made and opened: *rd the driver's read end (which never reads: it only keeps the
 * writer's open from waiting), *wr the writer's end for trace-gather-points' fd 3. */
static int fifo_open(const frames_t *F, int *rd, int *wr)
{
    char p[PATH_MAX + 32];
    snprintf(p, sizeof p, "%s/direct.fifo", F->out);
    unlink(p);
    if (mkfifo(p, 0600) != 0) {
        fsay(F, "cannot make the FIFO '%s': %s", p, strerror(errno));
        return 3;
    }
    *rd = open(p, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    *wr = *rd >= 0 ? open(p, O_WRONLY | O_CLOEXEC) : -1;
    if (*rd < 0 || *wr < 0) {
        fsay(F, "cannot open the FIFO '%s': %s", p, strerror(errno));
        return 3;
    }
    return 0;
}

/* ---- the progress line on a terminal: a thread that looks at the frames written ---- */

static volatile int progress_stop;
static double frame_mtime(const frames_t *F, int f)
{
    char p[PATH_MAX + 32];
    snprintf(p, sizeof p, "%s/frame-%04d.%s", F->out, f, F->png ? "png" : "exr");
    struct stat sb;
    if (stat(p, &sb) != 0)
        return -1;
    return (double)sb.st_mtim.tv_sec + 1e-9 * (double)sb.st_mtim.tv_nsec;
}
static double epoch_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
static void progress_line(const frames_t *F, int k, double now, double f0)
{
    if (k == 0) {
        fprintf(stderr, "\rframes: frame %d of %d (time left known after frame 0)   ", 1, F->n);
        return;
    }
    double m = k > 1 ? (now - F->t0 - f0) / (k - 1) : f0;
    fprintf(stderr, "\rframes: frame %d of %d (about %.1f s left)   ", k + 1, F->n, m * (F->n - k));
}
static void *progress_thread(void *arg)
{
    const frames_t *F = arg;
    int shown = -1;
    double f0 = 0;
    for (;;) {
        int last = progress_stop; /* set once every stage has ended: one more look, then done */
        int done = 0;
        while (done < F->n && frame_mtime(F, done) >= 0)
            done++;
        if (done >= 1 && f0 == 0)
            f0 = frame_mtime(F, 0) - F->t0;
        while (shown < done && shown < F->n - 1) {
            shown++;
            double t = shown > 0 ? frame_mtime(F, shown - 1) : epoch_now();
            progress_line(F, shown, t, f0);
        }
        if (last)
            break;
        struct timespec ts = {0, 50000000};
        nanosleep(&ts, NULL);
    }
    return NULL;
}

/* ---- the scenes of the path ---- */

/* Every frame's scene: u runs from -0.5 to 0.5 along the path (0 for one frame). The camera
 * orbits its look-at point about the world up axis (y), keeping its height; or every point
 * light moves along x. Products are kept apart from sums (no fused multiply-add), so that each
 * value is the one pipelines/frames' jq computed. */
static int write_scenes(frames_t *F, json_t *scene)
{
    double deg = strtod(F->v[F_DEGREES], NULL), shift = strtod(F->v[F_SHIFT], NULL);
    json_t *cam = json_object_get(scene, "camera"), *eye = json_object_get(cam, "eye"),
           *look = json_object_get(cam, "look_at");
    double e0 = json_number_value(json_array_get(eye, 0)), e1 = json_number_value(json_array_get(eye, 1)),
           e2 = json_number_value(json_array_get(eye, 2)), l0 = json_number_value(json_array_get(look, 0)),
           l2 = json_number_value(json_array_get(look, 2));
    json_t *lights = json_object_get(scene, "point_lights");
    size_t nl = json_array_size(lights);
    double *lx = calloc(nl + 1, sizeof *lx);
    for (size_t i = 0; i < nl; i++)
        lx[i] = json_number_value(json_array_get(json_object_get(json_array_get(lights, i), "position"), 0));
    for (int f = 0; f < F->n; f++) {
        volatile double u = F->n > 1 ? (double)f / (double)(F->n - 1) - 0.5 : 0.0;
        if (F->camera) {
            volatile double ud = u * deg, upi = ud * 3.141592653589793, a = upi / 180;
            volatile double x = e0 - l0, z = e2 - l2, c = cos(a), s = sin(a);
            volatile double xc = x * c, zs = z * s, xs = x * s, zc = z * c;
            volatile double n0 = l0 + xc, n2 = l2 - xs;
            double eye_x = n0 + zs, eye_z = n2 + zc;
            json_t *ne = json_pack("[f, f, f]", eye_x, e1, eye_z);
            json_object_set_new(cam, "eye", ne);
        } else {
            for (size_t i = 0; i < nl; i++) {
                json_t *pos = json_object_get(json_array_get(lights, i), "position");
                volatile double us = u * shift;
                json_array_set_new(pos, 0, json_real(lx[i] + us));
            }
        }
        char p[PATH_MAX + 32];
        scene_path(F, f, p, sizeof p);
        errno = 0;
        if (json_dump_file(scene, p, JSON_COMPACT | JSON_REAL_PRECISION(17)) != 0) {
            free(lx);
            fsay(F, "cannot write the frame's scene '%s': %s", p, strerror(errno ? errno : EIO));
            return 3;
        }
    }
    free(lx);
    return 0;
}

/* ---- STREAM=1: one pipeline of resident stages ---- */

static int run_stream(frames_t *F)
{
    char p[PATH_MAX + 64], s0[PATH_MAX + 32], map[PATH_MAX + 32], sorted[PATH_MAX + 32], fifo[PATH_MAX + 32];
    snprintf(map, sizeof map, "%s/map.pm", F->out);
    snprintf(sorted, sizeof sorted, "%s/sorted.pm", F->out);
    snprintf(fifo, sizeof fifo, "%s/direct.fifo", F->out);
    scene_path(F, 0, s0, sizeof s0);
    int sort = strcmp(F->v[F_ORDER], "none") != 0, status = 0;
    run_t R = {.fifo_rd = -1, .composite = -1};
    cmd_t c[6] = {0};
    /* the part that does not change: the map (camera) or the sorted queries (light), once */
    {
        run_t R0 = {.fifo_rd = -1, .composite = -1};
        int fds[2];
        if ((status = pipe_or_say(F, fds)) != 0)
            return status;
        int out = -1;
        if (F->camera) {
            prog(F, &c[0], "trace-photons");
            add(&c[0], s0);
            photon_opts(F, &c[0]);
            threads(F, &c[0]);
            add(&c[0], "-o");
            add(&c[0], "-");
            stats(F, &c[0], "trace-photons");
            prog(F, &c[1], "build-photonmap");
            add(&c[1], "-");
            threads(F, &c[1]);
            add(&c[1], "-o");
            add(&c[1], map);
            stats(F, &c[1], "build-photonmap");
        } else {
            prog(F, &c[0], "trace-gather-points");
            add(&c[0], s0);
            eye_opts(F, &c[0]);
            threads(F, &c[0]);
            add(&c[0], "-o");
            add(&c[0], "-");
            if (sort)
                sort_stream(F, &c[1]);
            out = open(sorted, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
            if (out < 0) {
                fsay(F, "cannot write '%s': %s", sorted, strerror(errno));
                close(fds[0]);
                close(fds[1]);
                cmd_free(&c[0]);
                cmd_free(&c[1]);
                return 3;
            }
        }
        if (c[1].n) {
            start(F, &R0, &c[0], -1, fds[1], -1);
            close(fds[1]);
            start(F, &R0, &c[1], fds[0], out, -1);
            close(fds[0]);
        } else {
            close(fds[0]);
            close(fds[1]);
            start(F, &R0, &c[0], -1, out, -1);
        }
        if (out >= 0)
            close(out);
        status = wait_all(F, &R0);
        cmd_free(&c[0]);
        cmd_free(&c[1]);
        if (status) {
            fsay(F, "%s", F->camera ? "frame 0: the photon stages failed" : "the eye stages failed");
            return status;
        }
    }
    F->t_map = epoch_now();
    int rd = -1, wr = -1;
    if (F->direct && (status = fifo_open(F, &rd, &wr)) != 0)
        return status;
    R.fifo_rd = rd;
    /* the stages of the pipeline, in order; the last is composite */
    int nc = 0;
    cmd_t *tg = NULL;
    if (F->camera) {
        tg = &c[nc++];
        prog(F, tg, "trace-gather-points");
        scenes(F, tg);
        eye_opts(F, tg);
        threads(F, tg);
        add(tg, "-o");
        add(tg, "-");
        if (F->direct) {
            add(tg, "--direct");
            add(tg, "/dev/fd/3");
        }
        stats(F, tg, "trace-gather-points");
        if (sort)
            sort_stream(F, &c[nc++]);
        gather_stream(F, &c[nc++], "queries", map, "-");
    } else {
        cmd_t *t = &c[nc++];
        prog(F, t, "trace-photons");
        scenes(F, t);
        photon_opts(F, t);
        threads(F, t);
        add(t, "-o");
        add(t, "-");
        stats(F, t, "trace-photons");
        cmd_t *b = &c[nc++];
        prog(F, b, "build-photonmap");
        add(b, "--stream");
        add(b, "-");
        threads(F, b);
        add(b, "-o");
        add(b, "-");
        stats(F, b, "build-photonmap");
        gather_stream(F, &c[nc++], "map", "-", sorted);
    }
    cmd_t *co = &c[nc++];
    prog(F, co, "composite");
    add(co, "--stream");
    if (F->direct)
        add(co, fifo);
    add(co, "-");
    snprintf(p, sizeof p, "%s/frame-%%04d.exr", F->out);
    add(co, "-o");
    add(co, p);
    if (F->png) {
        snprintf(p, sizeof p, "%s/frame-%%04d.png", F->out);
        add(co, "--png");
        add(co, p);
    }
    stats(F, co, "composite");
    /* MOVE=light: the direct light of every frame's lights, beside the photons */
    cmd_t side = {0};
    if (!F->camera && F->direct) {
        prog(F, &side, "trace-gather-points");
        add(&side, "--no-queries");
        scenes(F, &side);
        eye_opts(F, &side);
        threads(F, &side);
        add(&side, "--direct");
        add(&side, "/dev/fd/3");
        stats(F, &side, "trace-gather-points");
        start(F, &R, &side, -1, -1, wr);
    }
    int in = -1;
    for (int i = 0; i < nc && status == 0; i++) {
        int fds[2] = {-1, -1};
        if (i + 1 < nc && (status = pipe_or_say(F, fds)) != 0)
            break;
        int k = start(F, &R, &c[i], in, fds[1], &c[i] == tg ? wr : -1);
        if (i + 1 == nc)
            R.composite = k;
        if (in >= 0)
            close(in);
        if (fds[1] >= 0)
            close(fds[1]);
        in = fds[0];
    }
    if (in >= 0)
        close(in);
    if (wr >= 0)
        close(wr);
    pthread_t th;
    int have_thread = 0;
    if (F->progress) {
        progress_stop = 0;
        have_thread = pthread_create(&th, NULL, progress_thread, F) == 0;
    }
    int w = wait_all(F, &R);
    if (have_thread) {
        progress_stop = 1;
        pthread_join(th, NULL);
        fputs("\r\033[K", stderr);
    }
    if (R.fifo_rd >= 0)
        close(R.fifo_rd);
    for (int i = 0; i < nc; i++)
        cmd_free(&c[i]);
    cmd_free(&side);
    unlink(fifo);
    if (status == 0)
        status = w;
    if (status) {
        unlink(map);
        unlink(sorted);
        fsay(F, "the frame pipeline failed (exit %d); the stage's message above names the frame", status);
    }
    return status;
}

/* ---- STREAM=0: every stage per frame ---- */

static int run_per_frame(frames_t *F, json_t *per)
{
    char map[PATH_MAX + 32], sorted[PATH_MAX + 32], dir[PATH_MAX + 32], ind[PATH_MAX + 32], gj[PATH_MAX + 32];
    snprintf(map, sizeof map, "%s/map.pm", F->out);
    snprintf(sorted, sizeof sorted, "%s/sorted.pm", F->out);
    snprintf(dir, sizeof dir, "%s/direct.pm", F->out);
    snprintf(ind, sizeof ind, "%s/indirect.pm", F->out);
    snprintf(gj, sizeof gj, "%s/gather.json", F->out);
    int reuse = !strcmp(F->v[F_REUSE], "1"), overlap = !strcmp(F->v[F_OVERLAP], "1");
    int sort = strcmp(F->v[F_ORDER], "none") != 0;
    printf("  %5s %8s %8s %8s %8s  (s)\n", "frame", "photons", "eye", "gather", "total");
    double frame0 = 0;
    int status = 0;
    cmd_t c[4] = {0}, g = {0}, co = {0}; /* freed at the end, whichever way the loop ends */
    for (int f = 0; f < F->n; f++) {
        char sc[PATH_MAX + 32];
        scene_path(F, f, sc, sizeof sc);
        if (F->progress)
            progress_line(F, f, epoch_now(), frame0);
        double t0 = epoch_now(), t1, t2, t3, t4;
        int reused = f > 0 && F->camera && reuse;
        run_t PH = {.fifo_rd = -1, .composite = -1}; /* the photon side, then the eye side */
        if (!reused) {
            int fds[2];
            if (pipe_or_say(F, fds)) {
                status = 3;
                goto out;
            }
            prog(F, &c[0], "trace-photons");
            add(&c[0], sc);
            photon_opts(F, &c[0]);
            threads(F, &c[0]);
            add(&c[0], "-o");
            add(&c[0], "-");
            prog(F, &c[1], "build-photonmap");
            add(&c[1], "-");
            threads(F, &c[1]);
            add(&c[1], "-o");
            add(&c[1], map);
            start(F, &PH, &c[0], -1, fds[1], -1);
            close(fds[1]);
            start(F, &PH, &c[1], fds[0], -1, -1);
            close(fds[0]);
        }
        int nph = PH.n;
        if (!overlap && nph) {
            int s = wait_range(F, &PH, 0, nph);
            if (s) {
                fsay(F, "frame %d: the photon stages failed", f);
                {
                    status = s;
                    goto out;
                }
            }
        }
        t1 = epoch_now();
        /* the eye side: trace-gather-points | hilbert-sort > sorted.pm */
        {
            run_t *E = &PH;
            int e0 = PH.n;
            int fds[2];
            if (pipe_or_say(F, fds)) {
                status = 3;
                goto out;
            }
            prog(F, &c[2], "trace-gather-points");
            add(&c[2], sc);
            eye_opts(F, &c[2]);
            threads(F, &c[2]);
            add(&c[2], "-o");
            add(&c[2], "-");
            if (F->direct) {
                add(&c[2], "--direct");
                add(&c[2], dir);
            }
            int out = open(sorted, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
            if (out < 0) {
                fsay(F, "cannot write '%s': %s", sorted, strerror(errno));
                {
                    status = 3;
                    goto out;
                }
            }
            start(F, E, &c[2], -1, sort ? fds[1] : out, -1);
            close(fds[1]);
            if (sort) {
                prog(F, &c[3], "hilbert-sort");
                add(&c[3], "-");
                add(&c[3], "--order");
                add(&c[3], F->v[F_ORDER]);
                threads(F, &c[3]);
                add(&c[3], "-o");
                add(&c[3], "-");
                start(F, E, &c[3], fds[0], out, -1);
            }
            close(fds[0]);
            close(out);
            int s = wait_range(F, E, e0, E->n);
            if (s) {
                wait_all(F, &PH);
                fsay(F, "frame %d: the eye stages failed", f);
                {
                    status = s;
                    goto out;
                }
            }
        }
        t2 = epoch_now();
        int sp_ = nph ? wait_range(F, &PH, 0, nph) : 0;
        if (sp_) {
            fsay(F, "frame %d: the photon stages failed", f);
            {
                status = sp_;
                goto out;
            }
        }
        t3 = epoch_now();
        for (int i = 0; i < 4; i++)
            cmd_free(&c[i]);
        /* the gather: frame 0 settles the kernel width, the later frames keep it */
        prog(F, &g, "simd-gather");
        opt(&g, "--radius", F->v[F_RADIUS]);
        opt(&g, "--k", F->v[F_K]);
        if (!F->v[F_RADIUS][0])
            opt(&g, "--radius", F->radius); /* after frame 0: the width it settled on */
        threads(F, &g);
        add(&g, map);
        add(&g, sorted);
        add(&g, "-o");
        add(&g, ind);
        add(&g, "--stats");
        add(&g, gj);
        pm_spawn_t sp = {.argv = g.a, .stdin_fd = -1, .stdout_fd = -1};
        pm_proc_status_t st;
        int code = pm_proc_run(&sp, &st) == PM_OK ? st.exit_code : 3;
        pm_proc_status_free(&st);
        cmd_free(&g);
        if (code) {
            fsay(F, "frame %d: simd-gather failed", f);
            {
                status = worst(&code, 1);
                goto out;
            }
        }
        if (f == 0 && !F->v[F_RADIUS][0]) {
            json_t *j = NULL;
            json_t *r = pm_proc_stats_load(gj, &j) == PM_OK ? json_object_get(j, "radius_m") : NULL;
            if (!json_is_number(r)) {
                json_decref(j);
                fsay(F, "frame 0: no radius in simd-gather's stats");
                {
                    status = 1;
                    goto out;
                }
            }
            /* the shortest text that reads back as the same double */
            double rv = json_number_value(r);
            for (int prec = 1; prec <= 17; prec++) {
                snprintf(F->radius, sizeof F->radius, "%.*g", prec, rv);
                if (strtod(F->radius, NULL) == rv)
                    break;
            }
            json_decref(j);
        }
        char fe[PATH_MAX + 32], fp[PATH_MAX + 32];
        snprintf(fe, sizeof fe, "%s/frame-%04d.exr", F->out, f);
        snprintf(fp, sizeof fp, "%s/frame-%04d.png", F->out, f);
        prog(F, &co, "composite");
        if (F->direct)
            add(&co, dir);
        add(&co, ind);
        add(&co, "-o");
        add(&co, fe);
        if (F->png) {
            add(&co, "--png");
            add(&co, fp);
        }
        pm_spawn_t sp2 = {.argv = co.a, .stdin_fd = -1, .stdout_fd = -1};
        code = pm_proc_run(&sp2, &st) == PM_OK ? st.exit_code : 3;
        pm_proc_status_free(&st);
        cmd_free(&co);
        if (code) {
            fsay(F, "frame %d: composite failed", f);
            {
                status = worst(&code, 1);
                goto out;
            }
        }
        t4 = epoch_now();
        if (f == 0)
            frame0 = t4 - t0;
        if (F->progress)
            fputs("\r\033[K", stderr);
        double ph = reused ? 0 : (overlap ? t3 : t1) - t0;
        char phs[32];
        snprintf(phs, sizeof phs, "%.3f", ph);
        printf("  %5d %8s %8.3f %8.3f %8.3f\n", f, reused ? "reused" : phs, t2 - t1, t4 - t3, t4 - t0);
        fflush(stdout);
        json_array_append_new(per,
                              json_pack("{s:i, s:f, s:b, s:f, s:f, s:f}", "frame", f, "photons_s", ph, "map_reused",
                                        reused, "eye_s", t2 - t1, "gather_composite_s", t4 - t3, "total_s", t4 - t0));
    }
    status = 0;
out:
    for (int i = 0; i < 4; i++)
        cmd_free(&c[i]);
    cmd_free(&g);
    cmd_free(&co);
    return status;
}

/* One-line checks of the parameters (exit 2 with the message set). */
static int is_count(const char *s)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    return s[0] >= '0' && s[0] <= '9' && *end == '\0' && errno == 0 && v >= 1 && v <= MAXF;
}
static int is_finite(const char *s)
{
    double d;
    return pm_parse_double(s, &d) == PM_OK && isfinite(d);
}
static int one_of(const char *v, const char *a, const char *b, const char *c)
{
    return !strcmp(v, a) || !strcmp(v, b) || (c && !strcmp(v, c));
}

static pm_result_t check(frames_t *F, int argc, char **argv)
{
    for (int i = 0; i < argc; i++) {
        char *eq = strchr(argv[i], '=');
        if (!eq)
            return pm_error_set(PM_ERR_USAGE, "unexpected argument '%s': parameters are NAME=VALUE", argv[i]);
        int k = 0;
        while (k < F_COUNT &&
               (strlen(fnames[k]) != (size_t)(eq - argv[i]) || strncmp(fnames[k], argv[i], eq - argv[i])))
            k++;
        if (k == F_COUNT)
            return pm_error_set(PM_ERR_USAGE,
                                "unknown parameter '%.*s' (known: DEGREES FRAMES HEIGHT K MODE MOVE ORDER OVERLAP "
                                "PHOTONS PIXEL PNG PRIMARY QUIET RADIUS REUSE SHIFT SPP STREAM THREADS WIDTH)",
                                (int)(eq - argv[i]), argv[i]);
        F->v[k] = eq + 1;
    }
    const char *const *v = F->v;
    if (!is_count(v[F_FRAMES]))
        return pm_error_set(PM_ERR_USAGE, "bad value for FRAMES '%s': expected a count of at least 1", v[F_FRAMES]);
    if (!one_of(v[F_MOVE], "camera", "light", NULL))
        return pm_error_set(PM_ERR_USAGE, "bad value for MOVE '%s': expected camera or light", v[F_MOVE]);
    if (!one_of(v[F_ORDER], "hilbert", "morton", "none"))
        return pm_error_set(PM_ERR_USAGE, "bad value for ORDER '%s': expected hilbert, morton or none", v[F_ORDER]);
    static const fparam_t bools[] = {F_QUIET, F_REUSE, F_STREAM, F_PNG, F_OVERLAP, F_SECONDARY_DIRECT};
    for (size_t i = 0; i < sizeof bools / sizeof bools[0]; i++)
        if (!one_of(v[bools[i]], "0", "1", NULL))
            return pm_error_set(PM_ERR_USAGE, "bad value for %s '%s': expected 0 or 1", fnames[bools[i]], v[bools[i]]);
    if (!one_of(v[F_MODE], "gather", "direct-vis", NULL))
        return pm_error_set(PM_ERR_USAGE, "bad value for MODE '%s': expected gather or direct-vis", v[F_MODE]);
    if (!one_of(v[F_DIFFUSE_DEPTH], "0", "1", "2"))
        return pm_error_set(PM_ERR_USAGE, "bad value for DIFFUSE_DEPTH '%s': expected 0, 1 or 2", v[F_DIFFUSE_DEPTH]);
    if (strcmp(v[F_DIFFUSE_DEPTH], "0") != 0 && strcmp(v[F_MODE], "gather") != 0)
        return pm_error_set(PM_ERR_USAGE,
                            "DIFFUSE_DEPTH=%s needs MODE=gather: diffuse bounces come before a gather point, and "
                            "direct-vis has none",
                            v[F_DIFFUSE_DEPTH]);
    if (!strcmp(v[F_SECONDARY_DIRECT], "1") && strcmp(v[F_MODE], "gather") != 0)
        return pm_error_set(
            PM_ERR_USAGE, "SECONDARY_DIRECT=1 needs MODE=gather: in direct-vis mode the queries are the primary hits, "
                          "whose light samples the map's estimate replaces");
    if (v[F_PIXEL][0] && !one_of(v[F_PIXEL], "box", "center", NULL))
        return pm_error_set(PM_ERR_USAGE, "bad value for PIXEL '%s': expected box or center", v[F_PIXEL]);
    if (v[F_PRIMARY][0] && !is_count(v[F_PRIMARY]))
        return pm_error_set(PM_ERR_USAGE, "bad value for PRIMARY '%s': expected a count of at least 1", v[F_PRIMARY]);
    if (!is_finite(v[F_DEGREES]))
        return pm_error_set(PM_ERR_USAGE, "bad value for DEGREES '%s': expected a finite number of degrees",
                            v[F_DEGREES]);
    if (!is_finite(v[F_SHIFT]))
        return pm_error_set(PM_ERR_USAGE, "bad value for SHIFT '%s': expected a finite distance in m", v[F_SHIFT]);
    return PM_OK;
}

int pm_frames_run(const char *me, const char *scene_arg, const char *outdir, int argc, char **argv, const char *bin,
                  const char *cmdline)
{
    static frames_t FF;
    frames_t *F = &FF;
    memset(F, 0, sizeof *F);
    F->me = me;
    F->scene_arg = scene_arg;
    F->bin = bin;
    for (int k = 0; k < F_COUNT; k++)
        F->v[k] = fdefaults[k];
    struct stat sb;
    if (stat(scene_arg, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        fsay(F, "cannot read scene '%s'", scene_arg);
        return 1;
    }
    if (check(F, argc, argv) != PM_OK) {
        fsay(F, "%s", pm_error_message());
        return 2;
    }
    F->n = atoi(F->v[F_FRAMES]);
    F->camera = !strcmp(F->v[F_MOVE], "camera");
    F->png = !strcmp(F->v[F_PNG], "1");
    F->stream = !strcmp(F->v[F_STREAM], "1") && !(F->camera && !strcmp(F->v[F_REUSE], "0"));
    F->direct = strcmp(F->v[F_MODE], "direct-vis") != 0; /* the map's estimate alone: direct light would count twice */
    F->progress = isatty(STDERR_FILENO) && strcmp(F->v[F_QUIET], "1") != 0;
    /* OUTDIR, held for the run */
    char mk[PATH_MAX];
    snprintf(mk, sizeof mk, "%s", outdir);
    for (char *s = mk + 1; *s; s++)
        if (*s == '/') {
            *s = '\0';
            mkdir(mk, 0777);
            *s = '/';
        }
    if (mkdir(mk, 0777) != 0 && errno != EEXIST) {
        fsay(F, "cannot create '%s': %s", outdir, strerror(errno));
        return 3;
    }
    char *real = realpath(outdir, NULL);
    if (!real) {
        fsay(F, "cannot create '%s'", outdir);
        return 3;
    }
    snprintf(F->out, sizeof F->out, "%s", real);
    free(real);
    int lock_fd = -1, status = pm_engine_lock(me, F->out, 0, cmdline, &lock_fd);
    if (status)
        return status;
    json_t *scene = NULL, *per = json_array(), *stages = json_object();
    /* the scene, mesh paths made absolute */
    {
        char dir[PATH_MAX];
        snprintf(dir, sizeof dir, "%s", scene_arg);
        char *slash = strrchr(dir, '/');
        if (slash)
            *slash = '\0';
        char *rd = realpath(slash ? (dir[0] ? dir : "/") : ".", NULL);
        snprintf(F->scene_dir, sizeof F->scene_dir, "%s", rd ? rd : ".");
        free(rd);
    }
    json_error_t je;
    scene = json_load_file(scene_arg, JSON_DECODE_ANY, &je);
    if (!json_is_object(scene)) {
        fsay(F, "cannot read scene '%s' as JSON", scene_arg);
        status = 1;
        goto done;
    }
    size_t i;
    json_t *m;
    json_array_foreach(json_object_get(scene, "meshes"), i, m)
    {
        const char *file = json_string_value(json_object_get(m, "file"));
        if (file && file[0] != '/') {
            char abs[2 * PATH_MAX + 2];
            snprintf(abs, sizeof abs, "%s/%s", F->scene_dir, file);
            json_object_set_new(m, "file", json_string(abs));
        }
    }
    static const char *const progs[] = {
        "trace-photons", "build-photonmap", "trace-gather-points", "hilbert-sort", "simd-gather", "composite", NULL};
    for (int k = 0; progs[k]; k++) {
        char p[PATH_MAX + 64];
        snprintf(p, sizeof p, "%s/%s", bin, progs[k]);
        if (access(p, X_OK) != 0) {
            fsay(F, "'%s' is not built (make)", p);
            status = 1;
            goto done;
        }
    }
    /* the scene loaded as the stages will load it: a scene they would refuse stops here, once */
    {
        pm_scene_t sc;
        memset(&sc, 0, sizeof sc);
        pm_result_t r = pm_scene_load(scene_arg, &sc);
        if (r != PM_OK) {
            fsay(F, "cannot load scene '%s': %s", scene_arg, pm_error_message());
            status = r == PM_ERR_INPUT || r == PM_ERR_USAGE ? 1 : 3;
            goto done;
        }
        size_t points = json_array_size(json_object_get(scene, "point_lights"));
        int sd_asked = !strcmp(F->v[F_SECONDARY_DIRECT], "1");
        F->sec_direct = sd_asked && pm_lights_count_at_gather(&sc) > 0;
        if (sd_asked && !F->sec_direct)
            fsay(F, "skipped secondary direct light: scene '%s' has no light the gather points sample", scene_arg);
        pm_scene_free(&sc);
        if (!F->camera && points == 0) {
            fsay(F, "MOVE=light: scene '%s' has no point lights to move (its area lights are mesh triangles)",
                 scene_arg);
            status = 1;
            goto done;
        }
    }
    F->t0 = epoch_now();
    if ((status = write_scenes(F, scene)) != 0)
        goto done;
    printf("frames: %s, %d frames, moving the %s%s\n", scene_arg, F->n, F->v[F_MOVE],
           F->stream ? ", resident stages" : "");
    fflush(stdout);
    char p[PATH_MAX + 64];
    if (F->stream) {
        /* five programs share the cores: a waiting OpenMP thread sleeps (the user's setting stands) */
        setenv("OMP_WAIT_POLICY", "passive", 0);
        /* what an earlier run left: its frames and stats */
        static const char *const olds[] = {"", "stats/", NULL};
        for (int k = 0; olds[k]; k++) {
            snprintf(p, sizeof p, "%s/%s", F->out, olds[k]);
            DIR *d = opendir(p);
            struct dirent *e;
            while (d && (e = readdir(d))) {
                size_t len = strlen(e->d_name);
                int frame = !strncmp(e->d_name, "frame-", 6) && len > 4 &&
                            (!strcmp(e->d_name + len - 4, ".exr") || !strcmp(e->d_name + len - 4, ".png"));
                int stat_file = k == 1 && len > 5 && !strcmp(e->d_name + len - 5, ".json");
                if (frame || stat_file) {
                    char q[2 * PATH_MAX];
                    snprintf(q, sizeof q, "%s/%s%s", F->out, olds[k], e->d_name);
                    unlink(q);
                }
            }
            if (d)
                closedir(d);
        }
        snprintf(p, sizeof p, "%s/stats", F->out);
        mkdir(p, 0777);
        if ((status = run_stream(F)) != 0)
            goto done;
        printf("  %5s %8s %8s %8s  (s)\n", "frame", "photons", "done", "total");
        double prev = F->t0;
        for (int f = 0; f < F->n; f++) {
            double t = frame_mtime(F, f);
            if (t < 0) {
                fsay(F, "frame %d: no '%s/frame-%04d.%s'", f, F->out, f, F->png ? "png" : "exr");
                status = 1;
                goto done;
            }
            int reused = F->camera && f > 0;
            char ph[32];
            snprintf(ph, sizeof ph, "%.3f", F->t_map - F->t0);
            printf("  %5d %8s %8.3f %8.3f\n", f, reused ? "reused" : F->camera ? ph : "stream", t - F->t0, t - prev);
            json_array_append_new(per, json_pack("{s:i, s:b, s:f, s:f}", "frame", f, "map_reused", reused, "done_s",
                                                 t - F->t0, "total_s", t - prev));
            prev = t;
        }
        static const char *const names[] = {"trace-photons",
                                            "build-photonmap",
                                            "trace-gather-points",
                                            "hilbert-sort",
                                            "simd-gather",
                                            "composite",
                                            NULL};
        for (int k = 0; names[k]; k++) {
            snprintf(p, sizeof p, "%s/stats/%s.json", F->out, names[k]);
            json_t *j = NULL;
            if (pm_proc_stats_load(p, &j) == PM_OK && j)
                json_object_set_new(stages, names[k], j);
        }
        snprintf(p, sizeof p, "%s/map.pm", F->out);
        unlink(p);
        snprintf(p, sizeof p, "%s/sorted.pm", F->out);
        unlink(p);
    } else {
        if ((status = run_per_frame(F, per)) != 0)
            goto done;
        snprintf(p, sizeof p, "%s/gather.json", F->out);
        json_t *j = NULL;
        if (pm_proc_stats_load(p, &j) == PM_OK && j)
            json_object_set_new(stages, "simd-gather", j); /* the last frame's gather */
        static const char *const tmp[] = {"map.pm", "direct.pm", "sorted.pm", "indirect.pm", "gather.json", NULL};
        for (int k = 0; tmp[k]; k++) {
            snprintf(p, sizeof p, "%s/%s", F->out, tmp[k]);
            unlink(p);
        }
    }
    {
        double total = epoch_now() - F->t0, fps = total > 0 ? F->n / total : 0;
        printf("frames: %d frames in %.3f s: %.2f frames per second\n", F->n, total, fps);
        json_t *root =
            json_pack("{s:s, s:i, s:s, s:b, s:b, s:i, s:f, s:f, s:O, s:O}", "scene", scene_arg, "frames", F->n, "move",
                      F->v[F_MOVE], "stream", F->stream, "secondary_direct", F->sec_direct, "diffuse_depth",
                      atoi(F->v[F_DIFFUSE_DEPTH]), "total_s", total, "fps", fps, "per_frame", per, "stages", stages);
        char tmpf[PATH_MAX + 64], dst[PATH_MAX + 64];
        snprintf(tmpf, sizeof tmpf, "%s/.frames.json.tmp", F->out);
        snprintf(dst, sizeof dst, "%s/frames.json", F->out);
        if (!root || json_dump_file(root, tmpf, JSON_INDENT(2) | JSON_REAL_PRECISION(6)) != 0 ||
            rename(tmpf, dst) != 0) {
            unlink(tmpf);
            fsay(F, "could not write '%s'", dst);
            status = 3;
        }
        json_decref(root);
    }
done:
    fflush(stdout);
    json_decref(scene);
    json_decref(per);
    json_decref(stages);
    if (lock_fd >= 0)
        close(lock_fd);
    return status;
}
