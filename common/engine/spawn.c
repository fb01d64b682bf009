/* spawn.c: a stage as a process (engine.h, "spawn"). posix_spawn with the stage's stdin and
 * stdout on the fds the driver gives (pipes between stages), its stderr passed through or
 * captured through a pipe, its wall time from spawn to exit. */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "base/timer.h"
#include "engine/engine.h"
#include "render/scene_cache.h"

extern char **environ;

struct pm_proc {
    pid_t pid;
    int err_fd; /* read end of the captured stderr, -1 when passed through */
    double t0;  /* s, pm_time_wall at spawn */
    char name[256];
};

void pm_proc_signal(const pm_proc_t *p, int sig)
{
    if (p && p->pid > 0)
        kill(p->pid, sig);
}

double pm_proc_cpu_s(const pm_proc_t *p)
{
    char path[64], buf[1024];
    snprintf(path, sizeof path, "/proc/%d/stat", (int)p->pid);
    FILE *f = fopen(path, "r");
    if (!f)
        return -1.0;
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    /* the command name (field 2) is in parentheses and may hold spaces: count from its end */
    const char *q = strrchr(buf, ')');
    unsigned long long ut = 0, stime = 0;
    if (!q || sscanf(q + 1, " %*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %llu %llu", &ut, &stime) != 2)
        return -1.0;
    long hz = sysconf(_SC_CLK_TCK);
    return hz > 0 ? (double)(ut + stime) / (double)hz : -1.0;
}

pm_result_t pm_proc_pipe(int fds_out[2])
{
    if (pipe2(fds_out, O_CLOEXEC) != 0)
        return pm_error_set(PM_ERR_IO, "cannot make a pipe: %s", strerror(errno));
    return PM_OK;
}

pm_result_t pm_proc_class(int exit_code)
{
    switch (exit_code) {
    case 0: return PM_OK;
    case 1: return PM_ERR_INPUT;
    case 2: return PM_ERR_USAGE;
    case 4: return PM_ERR_INTERNAL;
    default: /* 3 (io, out of memory) and a signal: the system, which a retry may cure */ return PM_ERR_IO;
    }
}

pm_result_t pm_proc_spawn(const pm_spawn_t *sp, pm_proc_t **out)
{
    *out = NULL;
    pm_proc_t *p = calloc(1, sizeof *p);
    if (!p)
        return pm_error_set(PM_ERR_NOMEM, "out of memory starting '%s'", sp->argv[0]);
    const char *base = strrchr(sp->argv[0], '/');
    snprintf(p->name, sizeof p->name, "%s", base ? base + 1 : sp->argv[0]);
    p->err_fd = -1;
    int errp[2] = {-1, -1};
    if (sp->capture_stderr && pm_proc_pipe(errp) != PM_OK) {
        free(p);
        return PM_ERR_IO;
    }
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    /* The pipes are close-on-exec: dup2 gives the child its ends as 0, 1 and 2 only. */
    if (sp->stdin_fd >= 0)
        posix_spawn_file_actions_adddup2(&fa, sp->stdin_fd, 0);
    if (sp->stdout_fd >= 0)
        posix_spawn_file_actions_adddup2(&fa, sp->stdout_fd, 1);
    if (errp[1] >= 0)
        posix_spawn_file_actions_adddup2(&fa, errp[1], 2);
    if (sp->extra_to > 2 && sp->extra_fd >= 0)
        posix_spawn_file_actions_adddup2(&fa, sp->extra_fd, sp->extra_to);
    for (int i = 0; i < sp->nclose; i++)
        if (sp->close_fds[i] > 2)
            posix_spawn_file_actions_addclose(&fa, sp->close_fds[i]);
    if (sp->cwd)
        posix_spawn_file_actions_addchdir_np(&fa, sp->cwd);
    p->t0 = pm_time_wall();
    int rc = posix_spawn(&p->pid, sp->argv[0], &fa, NULL, sp->argv, sp->env ? sp->env : environ);
    posix_spawn_file_actions_destroy(&fa);
    if (errp[1] >= 0)
        close(errp[1]);
    if (rc != 0) {
        if (errp[0] >= 0)
            close(errp[0]);
        free(p);
        return pm_error_set(PM_ERR_IO, "cannot start '%s': %s", sp->argv[0], strerror(rc));
    }
    p->err_fd = errp[0];
    *out = p;
    return PM_OK;
}

/* Reads fd to its end into a malloc'd string. */
static char *slurp(int fd)
{
    size_t cap = 4096, n = 0;
    char *s = malloc(cap);
    if (!s)
        return NULL;
    for (;;) {
        if (n + 1 >= cap) {
            char *t = realloc(s, cap * 2);
            if (!t)
                break;
            s = t;
            cap *= 2;
        }
        ssize_t got = read(fd, s + n, cap - 1 - n);
        if (got < 0 && errno == EINTR)
            continue;
        if (got <= 0)
            break;
        n += (size_t)got;
    }
    s[n] = '\0';
    return s;
}

/* How the child ended, from waitpid's status, into status_out. */
static void set_status(int ws, pm_proc_status_t *status_out)
{
    if (WIFSIGNALED(ws)) {
        status_out->signal = WTERMSIG(ws);
        status_out->exit_code = 128 + status_out->signal;
    } else {
        status_out->exit_code = WEXITSTATUS(ws);
    }
}

pm_result_t pm_proc_wait_any(pm_proc_t *const *procs, int n, int *which_out, pm_proc_status_t *status_out)
{
    memset(status_out, 0, sizeof *status_out);
    *which_out = -1;
    for (;;) {
        int ws = 0;
        pid_t r = waitpid(-1, &ws, 0);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0)
            return pm_error_set(PM_ERR_INTERNAL, "waiting for a stage: %s", strerror(errno));
        for (int i = 0; i < n; i++) {
            pm_proc_t *p = procs[i];
            if (!p || p->pid != r)
                continue;
            if (p->err_fd >= 0) {
                status_out->err = slurp(p->err_fd);
                close(p->err_fd);
            }
            status_out->wall_s = pm_time_wall() - p->t0;
            set_status(ws, status_out);
            free(p);
            *which_out = i;
            return PM_OK;
        }
        /* a child that is none of these (none is expected): reaped, and waited past */
    }
}

pm_result_t pm_proc_wait(pm_proc_t *p, pm_proc_status_t *status_out)
{
    memset(status_out, 0, sizeof *status_out);
    if (p->err_fd >= 0) { /* read before waiting: a full pipe would block the stage forever */
        status_out->err = slurp(p->err_fd);
        close(p->err_fd);
    }
    int ws = 0;
    pid_t r;
    do
        r = waitpid(p->pid, &ws, 0);
    while (r < 0 && errno == EINTR);
    status_out->wall_s = pm_time_wall() - p->t0;
    pm_result_t res = PM_OK;
    if (r < 0) {
        res = pm_error_set(PM_ERR_IO, "cannot wait for '%s': %s", p->name, strerror(errno));
        status_out->exit_code = 4;
    } else {
        set_status(ws, status_out);
    }
    free(p);
    return res;
}

void pm_proc_status_free(pm_proc_status_t *st)
{
    free(st->err);
    st->err = NULL;
}

pm_result_t pm_proc_run(const pm_spawn_t *sp, pm_proc_status_t *status_out)
{
    pm_proc_t *p;
    memset(status_out, 0, sizeof *status_out);
    pm_result_t r = pm_proc_spawn(sp, &p);
    if (r != PM_OK)
        return r;
    return pm_proc_wait(p, status_out);
}

pm_result_t pm_proc_stats_load(const char *path, json_t **j_out)
{
    json_error_t e;
    *j_out = json_load_file(path, 0, &e);
    if (!*j_out)
        return pm_error_set(PM_ERR_INPUT, "cannot read the stage's statistics '%s': %s", path, e.text);
    return PM_OK;
}

pm_result_t pm_engine_bin(char *out, size_t cap)
{
    const char *env = getenv("BIN");
    if (env && env[0]) {
        char *real = realpath(env, NULL);
        if (!real)
            return pm_error_set(PM_ERR_USAGE, "no program directory '%s'", env);
        snprintf(out, cap, "%s", real);
        free(real);
        return PM_OK;
    }
    char self[4096];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    self[n > 0 ? n : 0] = '\0';
    char *slash = strrchr(self, '/');
    if (slash)
        *slash = '\0';
    snprintf(out, cap, "%s", self);
    return PM_OK;
}

void pm_engine_say(const char *me, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s: ", me);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

const char *pm_engine_scene_cache(const char *outdir, char *out, size_t cap)
{
    const char *env = getenv("PMTK_SCENE_CACHE");
    char cwd[4096];
    if (env && env[0] && env[0] != '/' && getcwd(cwd, sizeof cwd)) {
        /* the stages run in OUTDIR: a relative name made absolute for them and for this process */
        snprintf(out, cap, "%s/%s", cwd, env);
        setenv("PMTK_SCENE_CACHE", out, 1);
    } else if (env)
        snprintf(out, cap, "%s", env);
    else
        snprintf(out, cap, "%s/scene.cache", outdir);
    return out;
}

void pm_engine_say_scene_cache(const char *me, const char *cache, const pm_scene_cache_status_t *st, int uncacheable)
{
    if (!cache[0])
        fprintf(stderr, "%s: scene cache: none (PMTK_SCENE_CACHE is empty)\n", me);
    else if (st->hit)
        fprintf(stderr, "%s: scene cache %s: read\n", me, cache);
    else if (uncacheable)
        fprintf(stderr, "%s: scene cache %s: not used (the meshes' import reads files pmtk cannot name)\n", me, cache);
    else if (st->written)
        fprintf(stderr, "%s: scene cache %s: written%s%s%s\n", me, cache, st->why[0] ? " (" : "", st->why,
                st->why[0] ? ")" : "");
    else
        fprintf(stderr, "%s: scene cache %s: not written (%s)\n", me, cache, st->why);
}

pm_result_t pm_engine_scene_load(const char *outdir, const char *scene, char *cache, size_t cap, pm_scene_t *sc,
                                 pm_scene_cache_status_t *st)
{
    pm_engine_scene_cache(outdir, cache, cap);
    return pm_scene_load_cached(scene, cache, 0, sc, st);
}

void pm_engine_scene_keep(const char *me, int verbose, const char *cache, const pm_scene_t *sc,
                          pm_scene_cache_status_t *st)
{
    if (cache[0] && !st->hit && !sc->uncacheable) {
        size_t len = strlen(st->why);
        if (pm_scene_cache_write(sc, cache) == PM_OK)
            st->written = 1;
        else
            snprintf(st->why + len, sizeof st->why - len, "; not written: %s", pm_error_message());
    }
    if (verbose)
        pm_engine_say_scene_cache(me, cache, st, sc->uncacheable);
}
