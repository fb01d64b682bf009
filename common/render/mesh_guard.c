/* mesh_guard.c: what stands between an untrusted mesh file and libassimp (docs/scene-format.md,
 * "Untrusted meshes"). The headers of PLY, OFF and STL files, whose readers assimp 5.2 lets
 * crash, loop or allocate without bound on a damaged header, are checked here first against
 * the file's size; then the whole scene's load, assimp's imports with it, runs in a forked
 * child with a time and a memory limit (pm_scene_load_guarded), so that a crash, a hang or a
 * memory blow-up inside assimp ends in one line naming the file, and the child hands the
 * loaded scene back through a pipe. */
#include "render/scene.h"

#include <assimp/cimport.h>
#include <assimp/scene.h>
#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <jansson.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "base/hash.h"
#include "render/scene_load.h"

#if defined(__SANITIZE_ADDRESS__)
#define GUARD_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define GUARD_ASAN 1
#endif
#endif

enum { PLY_HEADER_MAX = 1 << 16 }; /* bytes; a longer header is refused */

/* The bytes of a PLY scalar type, 0 when name is none. */
static int ply_type_size(const char *name)
{
    static const struct {
        const char *name;
        int size;
    } types[] = {{"char", 1},  {"uchar", 1},   {"int8", 1},   {"uint8", 1},  {"short", 2}, {"ushort", 2},
                 {"int16", 2}, {"uint16", 2},  {"int", 4},    {"uint", 4},   {"int32", 4}, {"uint32", 4},
                 {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
    for (size_t i = 0; i < sizeof types / sizeof *types; i++)
        if (strcmp(types[i].name, name) == 0)
            return types[i].size;
    return 0;
}

/* The PLY header of path (its first n bytes in buf, size bytes in all): well formed, every line
 * of format, element and property one assimp reads right, and every element's count within what the bytes after the
 * header can hold (at least a byte per ASCII value, the scalar sizes per binary record). */
static pm_result_t check_ply(const char *path, const char *buf, size_t n, uint64_t size)
{
    const char *end = memmem(buf, n, "\nend_header", 11); /* a line of its own */
    end = end ? end + 1 : NULL;
    if (!end || (size_t)(end - buf) + 11 > n || (end[10] != '\n' && end[10] != '\r'))
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': PLY header has no end_header line within its first %d bytes",
                            path, PLY_HEADER_MAX);
    for (const char *p = buf; p < end; p++)
        if ((unsigned char)*p > 0x7e || ((unsigned char)*p < 0x20 && *p != '\n' && *p != '\r' && *p != '\t'))
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': PLY header byte %zu is 0x%02x, not text", path,
                                (size_t)(p - buf), (unsigned char)*p);
    uint64_t body = size - (uint64_t)(end + 11 + (end[10] == '\r' && end[11] == '\n') - buf);
    int format = -1, lineno = 0, have_element = 0;
    double need = 0.0, count = 0.0, per_record = 0.0; /* bytes the elements need at least */
    for (const char *line = buf; line < end;) {
        const char *eol = memchr(line, '\n', (size_t)(end - line));
        size_t len = eol ? (size_t)(eol - line) : (size_t)(end - line);
        char text[256], w[4][64] = {"", "", "", ""};
        lineno++;
        if (len >= sizeof text)
            return pm_error_set(PM_ERR_INPUT, "mesh '%s': PLY header line %d is %zu bytes long", path, lineno, len);
        memcpy(text, line, len);
        line += len + 1;
        while (len && (text[len - 1] == '\r' || text[len - 1] == ' ' || text[len - 1] == '\t'))
            len--;
        text[len] = '\0';
        int nw = sscanf(text, "%63s %63s %63s %63s", w[0], w[1], w[2], w[3]);
        if (lineno == 1) {
            if (strcmp(w[0], "ply") != 0 || nw != 1)
                return pm_error_set(PM_ERR_INPUT, "mesh '%s': PLY header does not begin with a line 'ply'", path);
        } else if (nw <= 0 || !strcmp(w[0], "comment") || !strcmp(w[0], "obj_info")) {
            continue;
        } else if (!strcmp(w[0], "format")) {
            format = !strcmp(w[1], "ascii")                  ? 0
                     : !strcmp(w[1], "binary_little_endian") ? 1
                     : !strcmp(w[1], "binary_big_endian")    ? 2
                                                             : -1;
            if (format < 0 || strcmp(w[2], "1.0") != 0)
                return pm_error_set(PM_ERR_INPUT,
                                    "mesh '%s': PLY header line %d: format '%s %s' is not ascii, "
                                    "binary_little_endian or binary_big_endian 1.0",
                                    path, lineno, w[1], w[2]);
        } else if (!strcmp(w[0], "element")) {
            char *e;
            errno = 0;
            unsigned long long c = strtoull(w[2], &e, 10);
            if (nw != 3 || !isdigit((unsigned char)w[2][0]) || *e || errno || c > PM_SCENE_MAX_TRIS)
                return pm_error_set(PM_ERR_INPUT,
                                    "mesh '%s': PLY header line %d: element '%s' count '%s' is not a "
                                    "count up to %u",
                                    path, lineno, w[1], w[2], PM_SCENE_MAX_TRIS);
            need += count * per_record;
            count = (double)c, per_record = 0.0, have_element = 1;
        } else if (!strcmp(w[0], "property")) {
            int list = !strcmp(w[1], "list");
            int sz = ply_type_size(list ? w[2] : w[1]);
            if (!have_element || !sz ||
                (list ? nw != 4 || !ply_type_size(w[3]) || !strcmp(w[2], "float") || !strcmp(w[2], "double") ||
                            !strcmp(w[2], "float32") || !strcmp(w[2], "float64")
                      : nw != 3))
                return pm_error_set(PM_ERR_INPUT,
                                    "mesh '%s': PLY header line %d: '%s' is not a property of an "
                                    "element (property TYPE NAME, property list COUNT-TYPE TYPE NAME)",
                                    path, lineno, text);
            per_record += format == 0 ? 2.0 : sz; /* ASCII: a digit and a space at least */
        } /* any other line: assimp skips it as a comment (Blender 2.47 wrote one), and so does this */
    }
    if (format < 0)
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': PLY header has no format line", path);
    need += count * per_record;
    if (need > (double)body)
        return pm_error_set(PM_ERR_INPUT,
                            "mesh '%s': PLY header declares records of at least %.0f bytes, but %" PRIu64
                            " follow the header",
                            path, need, body);
    return PM_OK;
}

/* The OFF header of path: its counts of vertices and faces within what its size can hold (an
 * ASCII vertex takes 6 bytes at least, a face 2). */
static pm_result_t check_off(const char *path, const char *buf, size_t n, uint64_t size)
{
    char text[PLY_HEADER_MAX + 1];
    memcpy(text, buf, n);
    text[n] = '\0';
    const char *p = text;
    int word = 0;
    unsigned long long counts[2] = {0, 0};
    int ncounts = 0;
    while (*p && ncounts < 2) {
        p += strspn(p, " \t\r\n");
        if (*p == '#') {
            p += strcspn(p, "\n");
            continue;
        }
        if (!*p)
            break;
        size_t tl = strcspn(p, " \t\r\n");
        if (!word) {
            word = 1; /* OFF, COFF, NOFF, ...: assimp's reader says which it takes */
            if (tl < 3 || strncmp(p + tl - 3, "OFF", 3) != 0)
                return pm_error_set(PM_ERR_INPUT, "mesh '%s': OFF file does not begin with an OFF keyword", path);
        } else {
            char *e;
            errno = 0;
            counts[ncounts] = strtoull(p, &e, 10);
            if (!isdigit((unsigned char)*p) || (size_t)(e - p) != tl || errno)
                return pm_error_set(PM_ERR_INPUT, "mesh '%s': OFF count '%.*s' is not a count", path, (int)tl, p);
            ncounts++;
        }
        p += tl;
    }
    if (ncounts < 2)
        return PM_OK; /* a binary or truncated header: assimp reports it */
    double need = 6.0 * (double)counts[0] + 2.0 * (double)counts[1];
    if (need > (double)size)
        return pm_error_set(PM_ERR_INPUT,
                            "mesh '%s': OFF header declares %llu vertices and %llu faces, more than its "
                            "%" PRIu64 " bytes can hold",
                            path, counts[0], counts[1], size);
    return PM_OK;
}

/* An STL file is binary (84 bytes, then 50 a triangle as its count says) or ASCII (solid). */
static pm_result_t check_stl(const char *path, const char *buf, size_t n, uint64_t size)
{
    if (n >= 84) {
        const unsigned char *c = (const unsigned char *)buf + 80;
        uint64_t count = c[0] | (uint32_t)c[1] << 8 | (uint32_t)c[2] << 16 | (uint32_t)c[3] << 24;
        if (size == 84 + 50 * count)
            return PM_OK;
    }
    size_t skip = 0;
    while (skip < n && isspace((unsigned char)buf[skip]))
        skip++;
    if (n - skip >= 5 && strncasecmp(buf + skip, "solid", 5) == 0)
        return PM_OK;
    return pm_error_set(PM_ERR_INPUT,
                        "mesh '%s': STL file of %" PRIu64 " bytes is neither binary (84 + 50 x its "
                        "triangle count) nor ASCII (solid ...)",
                        path, size);
}

pm_result_t pm_scene_mesh_precheck(const char *path)
{
    static char buf[PLY_HEADER_MAX];
    FILE *f = fopen(path, "rb");
    if (!f)
        return pm_error_set(pm_result_of_errno(errno), "cannot open mesh '%s': %s", path, strerror(errno));
    struct stat st;
    size_t n = fread(buf, 1, sizeof buf, f);
    int bad = ferror(f) || fstat(fileno(f), &st) != 0;
    int e = errno;
    fclose(f);
    if (bad)
        return pm_error_set(pm_result_of_errno(e), "cannot read mesh '%s': %s", path, strerror(e));
    size_t len = strlen(path);
    const char *ext = len > 4 ? path + len - 4 : "";
    /* assimp knows PLY by its first bytes whatever the name */
    if (n >= 4 && (memcmp(buf, "ply\n", 4) == 0 || memcmp(buf, "ply\r", 4) == 0))
        return check_ply(path, buf, n, (uint64_t)st.st_size);
    if (strcasecmp(ext, ".ply") == 0)
        return pm_error_set(PM_ERR_INPUT, "mesh '%s': a .ply file that does not begin with a line 'ply'", path);
    if (strcasecmp(ext, ".off") == 0)
        return check_off(path, buf, n, (uint64_t)st.st_size);
    if (strcasecmp(ext, ".stl") == 0)
        return check_stl(path, buf, n, (uint64_t)st.st_size);
    return PM_OK;
}

/* A limit from the environment: name's value (a whole number, 0 turns the guard off) or dflt. */
static long env_limit(const char *name, long dflt)
{
    const char *v = getenv(name);
    if (!v || !*v)
        return dflt;
    char *e;
    errno = 0;
    long x = strtol(v, &e, 10);
    return *e || errno || x < 0 ? -1 : x;
}

/* A process's resident memory and its data segment in MiB, from /proc (pid 0: this one); 0
 * when they cannot be read. */
static void statm_mib(pid_t pid, long *rss_out, long *data_out)
{
    char p[64];
    if (pid)
        snprintf(p, sizeof p, "/proc/%d/statm", (int)pid);
    else
        snprintf(p, sizeof p, "/proc/self/statm");
    FILE *f = fopen(p, "r");
    long v[6] = {0, 0, 0, 0, 0, 0};
    int ok = f && fscanf(f, "%ld %ld %ld %ld %ld %ld", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5]) == 6;
    if (f)
        fclose(f);
    double page = (double)sysconf(_SC_PAGESIZE) / (1024.0 * 1024.0);
    *rss_out = ok ? (long)((double)v[1] * page) : 0;
    *data_out = ok ? (long)((double)v[5] * page) : 0;
}

/* The limits (seconds, MiB; 0 off), or a usage error for a value that is not a whole number. */
static pm_result_t import_limits(long *secs, long *mib)
{
    *secs = env_limit("PMTK_IMPORT_SECONDS", 60), *mib = env_limit("PMTK_IMPORT_MB", 4096);
    if (*secs < 0 || *mib < 0)
        return pm_error_set(PM_ERR_USAGE,
                            "PMTK_IMPORT_SECONDS '%s' and PMTK_IMPORT_MB '%s' must be whole numbers "
                            "(0: no limit)",
                            getenv("PMTK_IMPORT_SECONDS") ? getenv("PMTK_IMPORT_SECONDS") : "",
                            getenv("PMTK_IMPORT_MB") ? getenv("PMTK_IMPORT_MB") : "");
    return PM_OK;
}

long pm_scene_import_mib(void)
{
    long secs, mib;
    return import_limits(&secs, &mib) == PM_OK ? mib : 0;
}

/* In the child of a guarded load (pm_scene_load_guarded): where it says what it is importing;
 * -1 elsewhere. */
static int guard_fd = -1;

/* A frame to the guarded load's parent: kind, the u64 length, the bytes. */
static void guard_put(char kind, const void *data, uint64_t n)
{
    if (guard_fd < 0)
        return;
    unsigned char head[9];
    head[0] = (unsigned char)kind;
    memcpy(head + 1, &n, sizeof n);
    const unsigned char *parts[2] = {head, data};
    size_t lens[2] = {sizeof head, (size_t)n};
    for (int k = 0; k < 2; k++)
        for (size_t at = 0; at < lens[k];) {
            ssize_t w = write(guard_fd, parts[k] + at, lens[k] - at);
            if (w < 0 && errno == EINTR)
                continue;
            if (w <= 0)
                _exit(12); /* the parent is gone or the pipe broken: nothing to report to */
            at += (size_t)w;
        }
}

void pm_scene_guard_entry(const char *scene, size_t index)
{
    char text[1400];
    int n = snprintf(text, sizeof text, "scene '%s': meshes[%zu]", scene, index);
    guard_put('M', text, n < 0 ? 0 : (uint64_t)strlen(text));
}

void pm_scene_guard_imported(void) { guard_put('D', "", 0); }

int pm_scene_guarded_child(void) { return guard_fd >= 0; }

void pm_scene_guard_importing(const char *path) { guard_put('P', path, strlen(path)); }

/* ---- the guarded load: the whole load in one child (render/scene_cache.c) ---- */

/* The frames a guarded child wrote, as the parent reads them after it ended. */
typedef struct {
    char entry[1400]; /* the last 'M': "scene 'S': meshes[I]" */
    char mesh[1200];  /* the last 'P': the file assimp was given */
    int in_import;    /* a 'P' with no 'D' after it: the child was inside assimp */
    int err_code;     /* an 'E': the load's failure */
    char err[PM_ERROR_MAX];
    const unsigned char *scene; /* an 'S': the scene's bytes */
    uint64_t nscene;
} frames_t;

static void read_frames(const unsigned char *d, size_t n, frames_t *f)
{
    memset(f, 0, sizeof *f);
    for (size_t at = 0; n - at >= 9;) {
        char kind = (char)d[at];
        uint64_t len;
        memcpy(&len, d + at + 1, sizeof len);
        at += 9;
        if (len > n - at)
            break; /* cut off by the child's death */
        const unsigned char *b = d + at;
        at += (size_t)len;
        if (kind == 'M')
            snprintf(f->entry, sizeof f->entry, "%.*s", (int)(len < sizeof f->entry ? len : sizeof f->entry - 1),
                     (const char *)b);
        else if (kind == 'P')
            snprintf(f->mesh, sizeof f->mesh, "%.*s", (int)(len < sizeof f->mesh ? len : sizeof f->mesh - 1),
                     (const char *)b),
                f->in_import = 1;
        else if (kind == 'D')
            f->in_import = 0;
        else if (kind == 'E' && len >= sizeof(int32_t)) {
            int32_t c;
            memcpy(&c, b, sizeof c);
            f->err_code = c ? c : PM_ERR_INTERNAL;
            snprintf(f->err, sizeof f->err, "%.*s",
                     (int)(len - sizeof c < sizeof f->err ? len - sizeof c : sizeof f->err - 1),
                     (const char *)b + sizeof c);
        } else if (kind == 'S')
            f->scene = b, f->nscene = len;
    }
}

/* What the parent has read of the child's pipe. */
typedef struct {
    int fd;
    unsigned char *p;
    size_t n, cap;
} pipe_buf_t;

/* One read of b's pipe onto its end (grown as needed): 1 bytes came, 0 the pipe is at its end (or
 * failed), -1 out of memory. */
static int read_some(pipe_buf_t *b)
{
    if (b->cap - b->n < 1 << 16) {
        size_t cap = b->cap ? 2 * b->cap : 1 << 20;
        unsigned char *q = realloc(b->p, cap);
        if (!q)
            return -1;
        b->p = q, b->cap = cap;
    }
    ssize_t got = read(b->fd, b->p + b->n, b->cap - b->n);
    if (got > 0)
        b->n += (size_t)got;
    return got > 0 || (got < 0 && errno == EINTR) ? 1 : 0;
}

pm_result_t pm_scene_load_guarded(const char *path, int keyed, unsigned char **bytes_out, size_t *n_out,
                                  int *unguarded_out)
{
    *bytes_out = NULL, *n_out = 0, *unguarded_out = 0;
    long secs, mib;
    pm_result_t r = import_limits(&secs, &mib);
    if (r != PM_OK)
        return r;
    if (secs == 0 && mib == 0) {
        *unguarded_out = 1; /* both off: the caller loads in its own process */
        return PM_OK;
    }
    long rss0, data0, rss;
    statm_mib(0, &rss0, &data0);
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) /* no other program started meanwhile holds the write end */
        return pm_error_set(pm_result_of_errno(errno), "scene '%s': cannot make a pipe for the guarded load: %s", path,
                            strerror(errno));
    fflush(NULL);
    pid_t parent = getpid();
    pid_t pid = fork();
    if (pid < 0) {
        int e = errno;
        close(fds[0]), close(fds[1]);
        return pm_error_set(pm_result_of_errno(e), "scene '%s': cannot fork the guarded load: %s", path, strerror(e));
    }
    if (pid == 0) {
        /* The child: the load, its warnings kept in the scene (the parent says them); stdout and
         * stderr to /dev/null, signals the default, the data segment capped as the trial's. */
        close(fds[0]);
        guard_fd = fds[1];
        /* it ends with its parent (a stage killed while it loads): it must not outlive it holding
         * what it inherited, the OUTDIR lock among them */
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        if (getppid() != parent)
            _exit(14);
        int null = open("/dev/null", O_RDWR);
        if (null >= 0) {
            dup2(null, STDOUT_FILENO);
            dup2(null, STDERR_FILENO);
        }
        static const int sigs[] = {SIGINT, SIGTERM, SIGHUP, SIGPIPE};
        for (size_t i = 0; i < sizeof sigs / sizeof *sigs; i++)
            signal(sigs[i], SIG_DFL);
#ifndef GUARD_ASAN
        if (mib > 0) {
            struct rlimit rl = {(rlim_t)(data0 + mib + 256) << 20, (rlim_t)(data0 + mib + 256) << 20};
            setrlimit(RLIMIT_DATA, &rl);
        }
#endif
        pm_scene_t s;
        unsigned char *bytes = NULL;
        size_t n = 0;
        pm_result_t cr = pm_scene_load_files(path, keyed, &s);
        if (cr == PM_OK) {
            cr = pm_scene_cache_encode(&s, &bytes, &n);
            pm_scene_free(&s);
        }
        if (cr != PM_OK) {
            const char *msg = pm_error_message();
            size_t ml = strlen(msg);
            unsigned char *e = malloc(sizeof(int32_t) + ml);
            if (!e)
                _exit(13);
            int32_t c = cr;
            memcpy(e, &c, sizeof c);
            memcpy(e + sizeof c, msg, ml);
            guard_put('E', e, sizeof c + ml);
            _exit(0);
        }
        guard_put('S', bytes, n);
        _exit(0);
    }
    close(fds[1]);
    /* The parent: reads what the child says while it watches its time and its memory. */
    pipe_buf_t in = {fds[0], NULL, 0, 0};
    struct timespec t0, now;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    const char *why = NULL;
    int status = 0, nomem = 0;
    for (int got = 1; got > 0;) {
        struct pollfd pf = {fds[0], POLLIN, 0};
        if (poll(&pf, 1, 2) > 0 && (got = read_some(&in)) < 0) {
            nomem = 1;
            why = "parent";
            break;
        }
        long data;
        statm_mib(pid, &rss, &data);
        clock_gettime(CLOCK_MONOTONIC, &now);
        double dt = (double)(now.tv_sec - t0.tv_sec) + 1e-9 * (double)(now.tv_nsec - t0.tv_nsec);
        if (mib > 0 && rss - rss0 > mib)
            why = "memory";
        else if (secs > 0 && dt > (double)secs)
            why = "time";
        if (why)
            break;
    }
    if (why && !nomem) {
        /* what it said before it was stopped is read to the end (which file assimp had): the
         * write end closes with it */
        kill(pid, SIGKILL);
        while (read_some(&in) > 0)
            ;
    }
    unsigned char *acc = in.p;
    size_t n = in.n;
    close(fds[0]);
    if (why)
        kill(pid, SIGKILL);
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR)
        ;
    if (nomem) {
        free(acc);
        return pm_error_set(PM_ERR_NOMEM, "scene '%s': out of memory reading the guarded load", path);
    }
    frames_t f;
    read_frames(acc, n, &f);
    pm_result_t out = PM_OK;
    if (!why && WIFEXITED(status) && WEXITSTATUS(status) == 0 && f.err_code) {
        out = pm_error_set(f.err_code, "%s", f.err);
    } else if (!why && WIFEXITED(status) && WEXITSTATUS(status) == 0 && f.scene) {
        /* the scene's bytes moved to the front of what was read, not copied: a large scene is
         * held twice at most (these bytes and the scene decoded from them) */
        memmove(acc, f.scene, (size_t)f.nscene);
        *bytes_out = acc, *n_out = (size_t)f.nscene;
        acc = NULL;
    } else if (f.in_import) {
        /* inside assimp: the trial's own words, with the entry as the in-process load says it */
        if (why && !strcmp(why, "memory"))
            pm_error_set(PM_ERR_INPUT,
                         "mesh '%s': assimp's import took more than %ld MiB (PMTK_IMPORT_MB) and was stopped", f.mesh,
                         mib);
        else if (why)
            pm_error_set(PM_ERR_INPUT,
                         "mesh '%s': assimp's import took more than %ld s (PMTK_IMPORT_SECONDS) and was stopped",
                         f.mesh, secs);
        else if (WIFSIGNALED(status))
            pm_error_set(PM_ERR_INPUT, "mesh '%s': assimp's import crashed (signal %d, %s)", f.mesh, WTERMSIG(status),
                         strsignal(WTERMSIG(status)));
        else
            pm_error_set(PM_ERR_INPUT, "mesh '%s': assimp's import failed (exit %d: a crash or out of memory%s)",
                         f.mesh, WEXITSTATUS(status), mib > 0 ? ", PMTK_IMPORT_MB" : "");
        if (f.entry[0])
            pm_error_prefix("%s", f.entry);
        out = PM_ERR_INPUT;
    } else if (why) {
        out = pm_error_set(PM_ERR_INPUT, "scene '%s': its load took more than %s and was stopped", path,
                           !strcmp(why, "memory") ? "PMTK_IMPORT_MB of memory" : "PMTK_IMPORT_SECONDS");
    } else {
        out = pm_error_set(PM_ERR_INTERNAL, "scene '%s': the guarded load ended without a scene (%s %d)", path,
                           WIFSIGNALED(status) ? "signal" : "exit",
                           WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status));
    }
    free(acc);
    return out;
}

/* The bytes [off, off + len) of glTF buffer b (bufs: the file's "buffers"; bin: a .glb's BIN
 * chunk, binlen bytes) into out; 0 when they cannot be had (a data: URI, a short file). */
static int gltf_bytes(const char *path, json_t *bufs, size_t b, const unsigned char *bin, size_t binlen, uint64_t off,
                      size_t len, unsigned char *out)
{
    json_t *buf = json_array_get(bufs, b);
    const char *uri = json_string_value(json_object_get(buf, "uri"));
    if (!buf)
        return 0;
    if (!uri) { /* a .glb's own buffer */
        if (!bin || off > binlen || len > binlen - off)
            return 0;
        memcpy(out, bin + off, len);
        return 1;
    }
    if (strncmp(uri, "data:", 5) == 0 || strstr(uri, "%"))
        return 0;
    char full[1200];
    pm_scene_resolve(path, uri, full, sizeof full);
    FILE *f = fopen(full, "rb");
    int ok = f && fseeko(f, (off_t)off, SEEK_SET) == 0 && fread(out, 1, len, f) == len;
    if (f)
        fclose(f);
    return ok;
}

pm_result_t pm_scene_gltf_bad_face(const char *path)
{
    /* the JSON, and a .glb's BIN chunk */
    FILE *f = fopen(path, "rb");
    if (!f)
        return PM_OK;
    unsigned char head[20];
    unsigned char *bin = NULL;
    size_t binlen = 0;
    json_t *root = NULL;
    if (fread(head, 1, 20, f) == 20 && memcmp(head, "glTF", 4) == 0) {
        uint32_t jlen = head[12] | (uint32_t)head[13] << 8 | (uint32_t)head[14] << 16 | (uint32_t)head[15] << 24;
        char *js = jlen < (64u << 20) ? malloc(jlen) : NULL;
        if (js && fread(js, 1, jlen, f) == jlen)
            root = json_loadb(js, jlen, 0, NULL);
        free(js);
        unsigned char ch[8];
        if (root && fread(ch, 1, 8, f) == 8) {
            binlen = ch[0] | (uint32_t)ch[1] << 8 | (uint32_t)ch[2] << 16 | (uint32_t)ch[3] << 24;
            bin = binlen < (1u << 30) ? malloc(binlen ? binlen : 1) : NULL;
            if (bin && fread(bin, 1, binlen, f) != binlen)
                free(bin), bin = NULL, binlen = 0;
        }
    } else {
        rewind(f);
        root = json_loadf(f, 0, NULL);
    }
    fclose(f);
    pm_result_t r = PM_OK;
    json_t *acc = json_object_get(root, "accessors"), *views = json_object_get(root, "bufferViews"),
           *bufs = json_object_get(root, "buffers"), *meshes = json_object_get(root, "meshes");
    for (size_t m = 0; r == PM_OK && m < json_array_size(meshes); m++) {
        json_t *prims = json_object_get(json_array_get(meshes, m), "primitives");
        for (size_t p = 0; r == PM_OK && p < json_array_size(prims); p++) {
            json_t *pr = json_array_get(prims, p);
            json_t *mode = json_object_get(pr, "mode");
            json_t *ia = json_array_get(acc, (size_t)json_integer_value(json_object_get(pr, "indices")));
            json_t *pa = json_array_get(
                acc, (size_t)json_integer_value(json_object_get(json_object_get(pr, "attributes"), "POSITION")));
            if ((mode && json_integer_value(mode) != 4) || !json_object_get(pr, "indices") || !ia || !pa)
                continue;
            json_int_t nverts = json_integer_value(json_object_get(pa, "count")),
                       count = json_integer_value(json_object_get(ia, "count")),
                       ct = json_integer_value(json_object_get(ia, "componentType"));
            json_t *bv = json_array_get(views, (size_t)json_integer_value(json_object_get(ia, "bufferView")));
            size_t cs = ct == 5121 ? 1 : ct == 5123 ? 2 : ct == 5125 ? 4 : 0;
            if (!bv || !cs || count <= 0 || count > (1 << 28))
                continue;
            uint64_t off = (uint64_t)json_integer_value(json_object_get(bv, "byteOffset")) +
                           (uint64_t)json_integer_value(json_object_get(ia, "byteOffset"));
            unsigned char *ix = malloc((size_t)count * cs);
            if (ix && gltf_bytes(path, bufs, (size_t)json_integer_value(json_object_get(bv, "buffer")), bin, binlen,
                                 off, (size_t)count * cs, ix))
                for (json_int_t i = 0; i < count - count % 3; i++) {
                    const unsigned char *q = ix + (size_t)i * cs;
                    uint64_t v =
                        cs == 1   ? q[0]
                        : cs == 2 ? (uint64_t)(q[0] | q[1] << 8)
                                  : (uint64_t)q[0] | (uint64_t)q[1] << 8 | (uint64_t)q[2] << 16 | (uint64_t)q[3] << 24;
                    if (v >= (uint64_t)nverts) {
                        const char *name = json_string_value(json_object_get(json_array_get(meshes, m), "name"));
                        r = pm_error_set(
                            PM_ERR_INPUT,
                            "mesh '%s': glTF mesh %zu ('%s') primitive %zu: face %lld names vertex %" PRIu64
                            " of %lld (assimp drops such faces)",
                            path, m, name ? name : "", p, (long long)(i / 3), v, (long long)nverts);
                        break;
                    }
                }
            free(ix);
        }
    }
    json_decref(root);
    free(bin);
    if (r == PM_OK) /* not found here (a data: URI, a strip): the file still loses faces */
        r = pm_error_set(PM_ERR_INPUT,
                         "mesh '%s': some faces name vertices their mesh does not have (assimp drops "
                         "such faces)",
                         path);
    return r;
}
