/* atomic.c: outputs that appear whole or not at all (see atomic.h): a temporary file beside the
 * target, fsync'ed and renamed into place; special files (FIFOs, devices) written through;
 * symbolic links followed; output sets renamed together; signal cleanup of temporary files. */
#define _POSIX_C_SOURCE 200809L
#include "base/atomic.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define PM_ATOMIC_SLOTS 16 /* temporary files open at once in one process */
#define PM_ATOMIC_HOPS 40  /* symbolic links followed before giving up (Linux's own limit) */
#define PM_ATOMIC_SUFFIX 8 /* bytes a temporary name adds to the base name: "." and ".XXXXXX" */

/* Paths the signal handler removes. A slot is published by storing its pointer last,
 * and the handler only reads pointers and calls unlink, which is async-signal-safe. */
static char *volatile cleanup_paths[PM_ATOMIC_SLOTS];

/* The set that commits on this thread join; NULL when none is open. */
static _Thread_local pm_atomic_set_t *current_set;

static void on_signal(int sig)
{
    for (int i = 0; i < PM_ATOMIC_SLOTS; i++)
        if (cleanup_paths[i])
            unlink(cleanup_paths[i]);
    signal(sig, SIG_DFL);
    raise(sig);
}

void pm_atomic_install_cleanup(void)
{
    static int installed;
    if (installed)
        return;
    installed = 1;
    /* SIGPIPE too: a stage writing stdout and a file must not leave the file's temporary
     * behind when its reader goes away. A signal the caller ignores (nohup) stays ignored. */
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP, SIGPIPE};
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        struct sigaction old, sa;
        if (sigaction(sigs[i], NULL, &old) == 0 && old.sa_handler == SIG_IGN)
            continue;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = on_signal;
        sigemptyset(&sa.sa_mask);
        sigaction(sigs[i], &sa, NULL);
    }
    /* A file-size limit (ulimit -f) then fails the write with EFBIG: an I/O error (exit 3)
     * that removes the temporary file, not a death by SIGXFSZ that leaves it behind. */
    signal(SIGXFSZ, SIG_IGN);
}

static int register_path(char *p)
{
    for (int i = 0; i < PM_ATOMIC_SLOTS; i++)
        if (!cleanup_paths[i]) {
            cleanup_paths[i] = p;
            return i;
        }
    return -1;
}

static void handle_init(pm_atomic_t *a)
{
    memset(a, 0, sizeof *a);
    a->slot = -1;
}

/* Unregisters and frees the names; the files are left as they are. */
static void release(pm_atomic_t *a)
{
    if (a->slot >= 0)
        cleanup_paths[a->slot] = NULL;
    free(a->tmp_path);
    free(a->target);
    free(a->path);
    handle_init(a);
}

/* The length of the directory part of path, its last '/' included (0 when none). */
static size_t dir_len(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? (size_t)(slash - path + 1) : 0;
}

/* Whether p names a file descriptor of this process (/dev/fd/N, /dev/stdout's /proc/self/fd/1):
 * a link the kernel resolves to whatever the descriptor holds, not a name to replace. */
static int fd_alias(const char *p)
{
    return strncmp(p, "/dev/fd/", 8) == 0 || (strncmp(p, "/proc/", 6) == 0 && strstr(p, "/fd/"));
}

/* The file a write to path lands on: path itself, or the end of its chain of symbolic links
 * (which need not exist: a dangling link names the file to create). *out is malloc'd;
 * *via_fd_out (may be NULL): whether the chain passed through a file descriptor's name. */
static pm_result_t resolve_links(const char *path, char **out, int *via_fd_out)
{
    char *cur = strdup(path);
    if (via_fd_out)
        *via_fd_out = 0;
    for (int hops = 0; cur; hops++) {
        if (via_fd_out && fd_alias(cur))
            *via_fd_out = 1;
        struct stat sb;
        if (lstat(cur, &sb) != 0 || !S_ISLNK(sb.st_mode)) {
            *out = cur;
            return PM_OK;
        }
        char link[PATH_MAX];
        ssize_t n = hops < PM_ATOMIC_HOPS ? readlink(cur, link, sizeof link - 1) : -1;
        if (n < 0) {
            int e = hops < PM_ATOMIC_HOPS ? errno : ELOOP;
            free(cur);
            return pm_error_set(pm_result_of_errno(e), "cannot create output '%s': %s", path, strerror(e));
        }
        link[n] = '\0';
        /* A relative link is relative to the directory that holds it. */
        size_t d = link[0] == '/' ? 0 : dir_len(cur);
        char *next = malloc(d + (size_t)n + 1);
        if (next) {
            memcpy(next, cur, d);
            memcpy(next + d, link, (size_t)n + 1);
        }
        free(cur);
        cur = next;
    }
    return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", path);
}

/* Fills out->path and decides what path is: a special file (written through), or a regular
 * file to replace (out->target, the end of its symbolic links). */
static pm_result_t classify(const char *path, pm_atomic_t *out)
{
    handle_init(out);
    struct stat sb;
    if (stat(path, &sb) == 0) {
        if (S_ISDIR(sb.st_mode))
            return pm_error_set(PM_ERR_USAGE, "output '%s' is a directory, not a file", path);
        out->special = !S_ISREG(sb.st_mode);
    }
    if (!(out->path = strdup(path)))
        return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", path);
    if (out->special)
        return PM_OK;
    int via_fd;
    pm_result_t r = resolve_links(path, &out->target, &via_fd);
    /* /dev/stdout or /dev/fd/N on a regular file: write to what the descriptor holds, as the
     * caller's shell opened it, rather than replace the file behind it. */
    if (r == PM_OK && via_fd) {
        free(out->target);
        out->target = NULL;
        out->special = 2;
        return PM_OK;
    }
    if (r == PM_OK && !out->target[dir_len(out->target)])
        r = pm_error_set(PM_ERR_USAGE, "output '%s' names a directory, not a file", path);
    if (r != PM_OK)
        release(out);
    return r;
}

/* Creates the temporary file with mkstemp (O_EXCL, never following a planted link) beside
 * out->target, or in $TMPDIR for a special file, registered for cleanup; *fd_out is open for
 * writing. The base name is shortened so that the temporary name fits NAME_MAX: a name of 250
 * bytes is legal, its temporary must be too. */
static pm_result_t make_temp(pm_atomic_t *out, int *fd_out)
{
    size_t n;
    if (out->special) {
        const char *dir = getenv("TMPDIR");
        if (!dir || !*dir)
            dir = "/tmp";
        n = strlen(dir) + 32;
        if ((out->tmp_path = malloc(n)))
            snprintf(out->tmp_path, n, "%s/.pmtk-output.XXXXXX", dir);
    } else {
        size_t d = dir_len(out->target), base = strlen(out->target + d);
        if (base > NAME_MAX - PM_ATOMIC_SUFFIX)
            base = NAME_MAX - PM_ATOMIC_SUFFIX;
        n = d + base + PM_ATOMIC_SUFFIX + 1;
        if ((out->tmp_path = malloc(n)))
            snprintf(out->tmp_path, n, "%.*s.%.*s.XXXXXX", (int)d, out->target, (int)base, out->target + d);
    }
    if (!out->tmp_path)
        return pm_error_set(PM_ERR_NOMEM, "out of memory opening '%s'", out->path);
    int fd = mkstemp(out->tmp_path);
    if (fd < 0) {
        int e = errno;
        free(out->tmp_path);
        out->tmp_path = NULL; /* nothing to remove */
        return pm_error_set(pm_result_of_errno(e), "cannot create output '%s': %s", out->path, strerror(e));
    }
    out->slot = register_path(out->tmp_path);
    /* mkstemp makes 0600; an output should get the permissions any new file would. */
    mode_t mask = umask(0);
    umask(mask);
    fchmod(fd, 0666 & ~mask);
    *fd_out = fd;
    return PM_OK;
}

/* Opens a special file for writing through: no creation, no truncation (a device or a FIFO
 * has nothing to truncate). A FIFO's open waits for its reader, as a shell's '>' does. A
 * regular file reached through a descriptor's name (special 2) is appended to: the shell
 * truncated it for '>' and did not for '>>'. */
static int open_special(const char *path, int special)
{
    /* /dev/fd/N on a pipe or FIFO the caller's shell opened for writing: a copy of N. Opened
     * anew, a FIFO's open would wait for a reader a second time, forever if the reader has
     * died since the shell's open returned. */
    char *end;
    long n = strncmp(path, "/dev/fd/", 8) == 0 ? strtol(path + 8, &end, 10) : -1;
    struct stat sb;
    if (n >= 0 && n <= INT_MAX && end != path + 8 && !*end && fstat((int)n, &sb) == 0 && S_ISFIFO(sb.st_mode) &&
        (fcntl((int)n, F_GETFL) & O_ACCMODE) != O_RDONLY)
        return fcntl((int)n, F_DUPFD_CLOEXEC, 0);
    return open(path, O_WRONLY | O_NOCTTY | O_CLOEXEC | (special == 2 ? O_APPEND : 0));
}

pm_result_t pm_atomic_reserve(const char *path, pm_atomic_t *out)
{
    if (strcmp(path, "-") == 0) {
        handle_init(out);
        return pm_error_set(PM_ERR_USAGE, "output '-': this output needs a file name, not stdout");
    }
    pm_result_t r = classify(path, out);
    int fd;
    if (r == PM_OK && (r = make_temp(out, &fd)) != PM_OK)
        release(out);
    if (r == PM_OK)
        close(fd); /* the library that writes by name reopens (and truncates) it */
    return r;
}

pm_result_t pm_atomic_open(const char *path, pm_atomic_t *out)
{
    if (strcmp(path, "-") == 0) {
        handle_init(out);
        out->f = stdout;
        return PM_OK;
    }
    pm_result_t r = classify(path, out);
    if (r != PM_OK)
        return r;
    int fd = -1;
    if (out->special) {
        if ((fd = open_special(path, out->special)) < 0) {
            int e = errno;
            release(out);
            return pm_error_set(pm_result_of_errno(e), "cannot open output '%s': %s", path, strerror(e));
        }
    } else if ((r = make_temp(out, &fd)) != PM_OK) {
        release(out);
        return r;
    }
    out->f = fdopen(fd, "wb");
    if (!out->f) {
        int e = errno;
        close(fd);
        pm_atomic_abort(out);
        return pm_error_set(pm_result_of_errno(e), "cannot open output '%s': %s", path, strerror(e));
    }
    return PM_OK;
}

pm_result_t pm_atomic_check(const char *path)
{
    if (strcmp(path, "-") == 0)
        return PM_OK;
    pm_atomic_t a;
    pm_result_t r = classify(path, &a);
    if (r != PM_OK)
        return r;
    int fd;
    if (a.special && access(path, W_OK) != 0)
        r = pm_error_set(pm_result_of_errno(errno), "cannot open output '%s': %s", path, strerror(errno));
    else if (!a.special && (r = make_temp(&a, &fd)) == PM_OK)
        close(fd);
    pm_atomic_abort(&a);
    return r;
}

/* 0 when the environment says PMTK_FSYNC=0: the caller (pipelines/render for the files of a
 * progressive pass) checks every file's checksum before it reuses it, so a file that a power
 * loss left torn is found and remade, and waiting for the disk buys nothing there. Anything
 * else: 1. */
static int want_sync(void)
{
    const char *e = getenv("PMTK_FSYNC");
    return !(e && strcmp(e, "0") == 0);
}

/* Everything before the rename: flush, check, fsync (the data must be on disk before its
 * name is), close. Sets the message on failure. */
static pm_result_t prepare(pm_atomic_t *a)
{
    int e = 0;
    const int do_sync = want_sync() && !a->no_sync;
    if (a->f) {
        errno = 0;
        if (fflush(a->f) != 0 || ferror(a->f))
            e = errno ? errno : EIO;
        /* EINVAL: a file system that cannot sync; nothing more can be done there. */
        else if (a->tmp_path && do_sync && fsync(fileno(a->f)) != 0 && errno != EINVAL)
            e = errno;
        if (a->f != stdout && fclose(a->f) != 0 && !e)
            e = errno ? errno : EIO;
        a->f = NULL;
    } else if (a->tmp_path && !a->special && do_sync) {
        /* A reserved name, written and closed by the library that writes by name. */
        int fd = open(a->tmp_path, O_RDONLY | O_CLOEXEC);
        if (fd < 0 || (fsync(fd) != 0 && errno != EINVAL))
            e = errno;
        if (fd >= 0)
            close(fd);
    }
    if (e)
        return pm_error_set(pm_result_of_errno(e), "cannot write '%s': %s", a->path ? a->path : "stdout", strerror(e));
    return PM_OK;
}

/* Copies a reserved temporary file into the special file it stands for. */
static pm_result_t copy_to_special(const pm_atomic_t *a)
{
    int in = open(a->tmp_path, O_RDONLY | O_CLOEXEC), out = in >= 0 ? open_special(a->path, a->special) : -1, e = 0;
    if (in < 0 || out < 0)
        e = errno;
    char buf[65536];
    for (ssize_t n; !e && (n = read(in, buf, sizeof buf)) != 0;) {
        if (n < 0) {
            e = errno == EINTR ? 0 : errno;
            continue;
        }
        for (ssize_t done = 0, w; !e && done<n; done += w> 0 ? w : 0)
            if ((w = write(out, buf + done, (size_t)(n - done))) < 0 && errno != EINTR)
                e = errno;
    }
    if (out >= 0 && close(out) != 0 && !e)
        e = errno;
    if (in >= 0)
        close(in);
    if (e)
        return pm_error_set(pm_result_of_errno(e), "cannot write '%s': %s", a->path, strerror(e));
    return PM_OK;
}

/* Syncs the directory that holds path, so that a rename into it survives a power loss. A
 * directory that cannot be opened or synced is left as it is: the file itself is synced. */
static void sync_dir(const char *path)
{
    size_t d = dir_len(path);
    char dir[PATH_MAX];
    if (d >= sizeof dir || !want_sync())
        return;
    if (d)
        memcpy(dir, path, d);
    else
        dir[d++] = '.';
    dir[d] = '\0';
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd >= 0) {
        fsync(fd);
        close(fd);
    }
}

/* Refuses a target that is there and is not a regular file: it may have become one (a FIFO,
 * a directory) since the output was opened. *created_out: whether the name is new. */
static pm_result_t check_target(const pm_atomic_t *a, int *created_out)
{
    struct stat sb;
    if (lstat(a->target, &sb) != 0) {
        *created_out = 1;
        return PM_OK;
    }
    *created_out = 0;
    if (!S_ISREG(sb.st_mode))
        return pm_error_set(PM_ERR_IO, "refusing to replace '%s': it is no longer a regular file", a->target);
    return PM_OK;
}

/* The rename (or, for a reserved special file, the copy) that puts a prepared output in
 * place. */
static pm_result_t finalize(pm_atomic_t *a, int *created_out)
{
    *created_out = 0;
    if (a->special)
        return copy_to_special(a);
    pm_result_t r = check_target(a, created_out);
    if (r != PM_OK)
        return r;
    if (rename(a->tmp_path, a->target) != 0)
        return pm_error_set(pm_result_of_errno(errno), "cannot rename output into '%s': %s", a->path, strerror(errno));
    sync_dir(a->target);
    return PM_OK;
}

static pm_result_t set_add(pm_atomic_set_t *s, pm_atomic_t *a)
{
    if (s->n == s->cap) {
        size_t cap = s->cap ? 2 * s->cap : 4;
        pm_atomic_t *v = realloc(s->items, cap * sizeof *v);
        if (!v)
            return pm_error_set(PM_ERR_NOMEM, "out of memory committing '%s'", a->path);
        s->items = v;
        s->cap = cap;
    }
    s->items[s->n++] = *a; /* the set owns the names and the cleanup slot now */
    handle_init(a);
    return PM_OK;
}

pm_result_t pm_atomic_commit(pm_atomic_t *a)
{
    pm_result_t r = prepare(a);
    if (r != PM_OK) {
        pm_atomic_abort(a);
        return r;
    }
    if (!a->tmp_path) { /* stdout or a special file: already written through */
        release(a);
        return PM_OK;
    }
    if (current_set) {
        if ((r = set_add(current_set, a)) != PM_OK)
            pm_atomic_abort(a);
        return r;
    }
    int created;
    r = finalize(a, &created);
    if (r != PM_OK) {
        pm_atomic_abort(a);
        return r;
    }
    if (a->special)
        unlink(a->tmp_path);
    release(a);
    return PM_OK;
}

void pm_atomic_abort(pm_atomic_t *a)
{
    if (a->f && a->f != stdout)
        fclose(a->f);
    a->f = NULL;
    if (a->tmp_path)
        unlink(a->tmp_path);
    release(a);
}

void pm_atomic_set_begin(pm_atomic_set_t *s)
{
    memset(s, 0, sizeof *s);
    s->open = 1;
    s->outer = current_set;
    if (!s->outer)
        current_set = s;
}

pm_result_t pm_atomic_set_commit(pm_atomic_set_t *s)
{
    if (!s->open)
        return PM_OK;
    s->open = 0;
    if (s->outer)
        return PM_OK; /* joined: the outer set holds the outputs */
    current_set = NULL;
    pm_result_t r = PM_OK;
    int created;
    /* Every target checked before the first rename, so that a refusal renames nothing. */
    for (size_t i = 0; i < s->n && r == PM_OK; i++)
        if (!s->items[i].special)
            r = check_target(&s->items[i], &created);
    unsigned char *made = calloc(s->n ? s->n : 1, 1);
    if (r == PM_OK && !made)
        r = pm_error_set(PM_ERR_NOMEM, "out of memory committing %zu outputs", s->n);
    size_t done = 0;
    for (; r == PM_OK && done < s->n; done++) {
        if ((r = finalize(&s->items[done], &created)) != PM_OK)
            break;
        made[done] = (unsigned char)created;
    }
    /* A rename that failed after others succeeded (a directory removed meanwhile): the names
     * this set created go again, so that a set appears whole or not at all where it can. */
    for (size_t i = 0; r != PM_OK && i < done; i++)
        if (made[i] && !s->items[i].special)
            unlink(s->items[i].target);
    for (size_t i = 0; i < s->n; i++) {
        if (i < done && !s->items[i].special)
            release(&s->items[i]);
        else
            pm_atomic_abort(&s->items[i]); /* not renamed, or a copy's temporary: removed */
    }
    free(made);
    free(s->items);
    s->items = NULL;
    s->n = s->cap = 0;
    return r;
}

void pm_atomic_set_abort(pm_atomic_set_t *s)
{
    if (!s->open)
        return;
    s->open = 0;
    if (s->outer)
        return;
    current_set = NULL;
    for (size_t i = 0; i < s->n; i++)
        pm_atomic_abort(&s->items[i]);
    free(s->items);
    s->items = NULL;
    s->n = s->cap = 0;
}

pm_result_t pm_atomic_set_end(pm_atomic_set_t *s, pm_result_t result)
{
    if (result == PM_OK)
        return pm_atomic_set_commit(s);
    pm_atomic_set_abort(s);
    return result;
}

/* A canonical name for a path that does not exist yet: its links followed, its directory
 * resolved by realpath, then its base name. NULL when that cannot be made. */
static char *canonical(const char *path)
{
    char *t = NULL, dir[PATH_MAX];
    if (resolve_links(path, &t, NULL) != PM_OK)
        return NULL;
    size_t d = dir_len(t);
    char *parent = d ? strndup(t, d) : strdup(".");
    char *res = parent && realpath(parent, dir) ? malloc(strlen(dir) + strlen(t + d) + 2) : NULL;
    if (res)
        sprintf(res, "%s/%s", dir, t + d);
    free(parent);
    free(t);
    return res;
}

int pm_atomic_same_file(const char *a, const char *b)
{
    struct stat sa, sb, sn;
    if (strcmp(a, "-") == 0 && strcmp(b, "-") == 0)
        return 1;
    if (strcmp(a, "-") == 0 || strcmp(b, "-") == 0) {
        /* stdout and a name for it (/dev/stdout, /dev/fd/1, the file or FIFO it was opened
         * on): one output by device and inode, unless both are /dev/null */
        const char *named = strcmp(a, "-") == 0 ? b : a;
        if (fstat(STDOUT_FILENO, &sa) != 0 || stat(named, &sb) != 0 || sa.st_dev != sb.st_dev || sa.st_ino != sb.st_ino)
            return 0;
        return !(stat("/dev/null", &sn) == 0 && sn.st_dev == sa.st_dev && sn.st_ino == sa.st_ino);
    }
    int ea = stat(a, &sa) == 0, eb = stat(b, &sb) == 0;
    if (ea && eb) {
        if (sa.st_dev != sb.st_dev || sa.st_ino != sb.st_ino)
            return 0;
        return !(stat("/dev/null", &sn) == 0 && sn.st_dev == sa.st_dev && sn.st_ino == sa.st_ino);
    }
    if (ea || eb) /* one name exists, the other does not: two files */
        return 0;
    if (strcmp(a, b) == 0)
        return 1;
    char *ca = canonical(a), *cb = canonical(b);
    int same = ca && cb && strcmp(ca, cb) == 0;
    free(ca);
    free(cb);
    return same;
}
