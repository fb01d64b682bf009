/* provenance.c: whether an intermediate is what the current settings would make (engine.h,
 * "provenance"). A file is kept when it reads whole (header, every record, the XXH3 trailer)
 * and its header records the SCENE part, the command lines and the content of each input the
 * driver would use now; nothing else counts, neither its date nor its path's history. */
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>
#if defined(__x86_64__)
/* libxxhash's run-time dispatch: XXH3 in AVX2 or AVX-512 where the CPU has them (as the
 * formats library and base/hash.c use), the same hash. */
#include <xxh_x86dispatch.h>
#endif

#include "engine/engine.h"
#include "formats/pmfile.h"

pm_result_t pm_prov_trailer(const char *path, uint64_t *hash_out)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return pm_error_set(PM_ERR_IO, "cannot open '%s': %s", path, strerror(errno));
    unsigned char b[8];
    int ok = fseek(f, -8, SEEK_END) == 0 && fread(b, 1, 8, f) == 8;
    fclose(f);
    if (!ok)
        return pm_error_set(PM_ERR_IO, "cannot read the trailer of '%s'", path);
    uint64_t h = 0;
    for (int i = 7; i >= 0; i--)
        h = h << 8 | b[i];
    *hash_out = h;
    return PM_OK;
}

pm_result_t pm_prov_command_line(int argc, char *const *argv, char **line_out)
{
    *line_out = NULL;
    char **kept = malloc(sizeof *kept * (size_t)(argc + 1));
    if (!kept)
        return pm_error_set(PM_ERR_NOMEM, "out of memory making a command line");
    int n = 0;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        if (i > 0 && (strcmp(a, "-q") == 0 || strcmp(a, "--quiet") == 0 || strncmp(a, "--threads=", 10) == 0 ||
                      strncmp(a, "--stats=", 8) == 0))
            continue;
        if (i > 0 && (strcmp(a, "--threads") == 0 || strcmp(a, "--stats") == 0)) {
            i++; /* and its value */
            continue;
        }
        kept[n++] = argv[i];
    }
    pm_header_t h;
    pm_header_init(&h, NULL);
    pm_result_t r = pm_header_add_command(&h, n, kept);
    free(kept);
    if (r == PM_OK && h.ncommands == 1) {
        *line_out = strdup(h.commands[0]);
        if (!*line_out)
            r = pm_error_set(PM_ERR_NOMEM, "out of memory making a command line");
    }
    pm_header_free(&h);
    return r;
}

/* A COMMAND line without " -q " and "--threads N": files made before the stages left these
 * out recorded them, and they change no output. Into out (cap bytes). */
static void norm_command(const char *line, char *out, size_t cap)
{
    size_t o = 0;
    const char *p = line;
    while (*p && o + 1 < cap) {
        if (p != line && p[-1] == ' ' && strncmp(p, "-q ", 3) == 0) {
            p += 3;
            continue;
        }
        if (p != line && p[-1] == ' ' && strcmp(p, "-q") == 0) {
            if (o > 0 && out[o - 1] == ' ')
                o--;
            break;
        }
        if (p != line && p[-1] == ' ' && strncmp(p, "--threads ", 10) == 0) {
            const char *q = p + 10;
            while (*q >= '0' && *q <= '9')
                q++;
            if (q > p + 10 && (*q == ' ' || *q == '\0')) {
                p = *q ? q + 1 : q;
                if (!*q && o > 0 && out[o - 1] == ' ')
                    o--;
                continue;
            }
        }
        out[o++] = *p++;
    }
    out[o] = '\0';
}

/* line without its second word (the scene file after the program's name), as pmtk quotes
 * words: bare, or in single quotes with a quote written '\\'' (header.c). In place. */
static void drop_second_word(char *line)
{
    char *w = strchr(line, ' ');
    if (!w)
        return;
    char *p = w + 1;
    if (*p == '\'') {
        p++;
        for (;;) {
            if (!*p)
                break;
            if (*p == '\'' && strncmp(p, "'\\''", 4) == 0) {
                p += 4;
                continue;
            }
            if (*p == '\'') {
                p++;
                break;
            }
            p++;
        }
    } else {
        while (*p && *p != ' ')
            p++;
    }
    memmove(w, p, strlen(p) + 1);
}

/* The message of a failed read as the one-line reason a file is corrupt: "checksum mismatch"
 * or the formats library's message with the file's path and the class left out. */
static void corrupt_why(const char *msg, const char *path, char *why, size_t cap)
{
    if (strstr(msg, "checksum mismatch")) {
        snprintf(why, cap, "checksum mismatch");
        return;
    }
    char buf[PM_ERROR_MAX];
    snprintf(buf, sizeof buf, "%s", msg);
    /* "truncated photon map 'DIR/photonmap.pm': record 3 of 40" -> without the path's quote */
    char q[1100];
    snprintf(q, sizeof q, " '%s'", path);
    char *at = strstr(buf, q);
    if (at)
        memmove(at, at + strlen(q), strlen(at + strlen(q)) + 1);
    snprintf(why, cap, "%s", buf);
}

/* Whether the file behind the open reader is whole: its size is the header's (header text,
 * byte-order marker, COUNT records of RECORD_SIZE bytes, the 8-byte trailer) and the trailer
 * is the XXH3-64 of every byte before it. The records' values are not checked here: the stage
 * that reads the file checks each as it reads it, and a file whose checksum holds was written
 * whole by a stage that checked them (docs/formats.md). Hashing the mapped file costs a small
 * part of what reading it record by record does, which is what a rerun with nothing to do pays. */
static pm_result_t whole(pm_reader_t *rd, const char *path, uint64_t size, uint64_t *hash_out)
{
    const pm_header_t *h = pm_reader_header(rd);
    uint64_t text = strlen(pm_reader_header_text(rd));
    if (h->record_size && h->count > (UINT64_MAX - text - 12) / h->record_size)
        return pm_error_set(PM_ERR_INPUT, "count %" PRIu64 " too large", h->count);
    uint64_t want = text + 4 + h->count * h->record_size + 8;
    if (size < want)
        return pm_error_set(PM_ERR_INPUT, "truncated: %" PRIu64 " bytes of %" PRIu64, size, want);
    if (size > want)
        return pm_error_set(PM_ERR_INPUT, "%" PRIu64 " bytes after the checksum", size - want);
    int fd = open(path, O_RDONLY);
    if (fd < 0)
        return pm_error_set(PM_ERR_IO, "cannot open '%s': %s", path, strerror(errno));
    /* Read through one buffer, not mapped: in a virtual machine a mapping's page tables cost
     * more than the copy (a rerun's files are in the page cache). */
    enum { CHUNK = 1 << 20 };
    unsigned char *buf = malloc(CHUNK);
    XXH3_state_t *st = XXH3_createState();
    if (!buf || !st) {
        close(fd);
        free(buf);
        XXH3_freeState(st);
        return pm_error_set(PM_ERR_NOMEM, "out of memory hashing '%s'", path);
    }
    XXH3_64bits_reset(st);
    uint64_t left = size - 8, off = 0, trailer = 0;
    int ok = 1;
    while (ok && left > 0) {
        size_t want_n = left < CHUNK ? (size_t)left : CHUNK;
        ssize_t n = pread(fd, buf, want_n, (off_t)off);
        if (n <= 0) {
            ok = 0;
            break;
        }
        XXH3_64bits_update(st, buf, (size_t)n);
        left -= (uint64_t)n, off += (uint64_t)n;
    }
    unsigned char tb[8];
    ok = ok && pread(fd, tb, 8, (off_t)off) == 8;
    close(fd);
    uint64_t got = XXH3_64bits_digest(st);
    XXH3_freeState(st);
    free(buf);
    if (!ok)
        return pm_error_set(PM_ERR_IO, "cannot read '%s': %s", path, strerror(errno));
    for (int i = 7; i >= 0; i--)
        trailer = trailer << 8 | tb[i];
    if (got != trailer)
        return pm_error_set(PM_ERR_INPUT, "checksum mismatch");
    *hash_out = trailer;
    return PM_OK;
}

pm_result_t pm_prov_check(const pm_prov_want_t *w, pm_prov_t *out)
{
    memset(out, 0, sizeof *out);
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", w->dir, w->name);
    struct stat sb;
    if (stat(path, &sb) != 0) {
        out->verdict = PM_PROV_MISSING;
        return PM_OK;
    }
    pm_reader_t *rd = NULL;
    pm_result_t r = pm_reader_open(path, NULL, 0, &rd);
    if (r == PM_OK)
        r = whole(rd, path, (uint64_t)sb.st_size, &out->hash);
    if (r == PM_ERR_NOMEM) {
        pm_reader_close(rd);
        return r;
    }
    if (r != PM_OK) {
        pm_reader_close(rd);
        out->verdict = PM_PROV_CORRUPT;
        corrupt_why(pm_error_message(), path, out->why, sizeof out->why);
        return PM_OK;
    }
    const pm_header_t *h = pm_reader_header(rd);
    out->count = h->count;
    out->verdict = PM_PROV_OK;
    const char *scene = pm_header_get(h, "SCENE");
    if (w->scene && (!scene || strcmp(scene, w->scene) != 0)) {
        out->verdict = PM_PROV_OTHER;
        snprintf(out->why, sizeof out->why, "scene '%s'", scene ? scene : "");
        goto done;
    }
    if (h->ncommands < w->ncommands) {
        out->verdict = PM_PROV_OTHER;
        snprintf(out->why, sizeof out->why, "%zu command lines", h->ncommands);
        goto done;
    }
    for (size_t i = 0; i < w->ncommands; i++) {
        static char got[PM_COMMAND_MAX + 8], want[PM_COMMAND_MAX + 8];
        norm_command(h->commands[h->ncommands - w->ncommands + i], got, sizeof got);
        norm_command(w->commands[i], want, sizeof want);
        if (w->external && i + 1 == w->ncommands) {
            /* a program outside the program directory may be a wrapper: the program it ran
             * records its own name; its options and files are what is compared */
            char *g = strchr(got, ' '), *v = strchr(want, ' ');
            memmove(got, g ? g : "", strlen(g ? g : "") + 1);
            memmove(want, v ? v : "", strlen(v ? v : "") + 1);
        }
        if (w->scene_arg && i + 1 == w->ncommands) {
            drop_second_word(got);
            drop_second_word(want);
        }
        if (strcmp(got, want) != 0) {
            out->verdict = PM_PROV_OTHER;
            snprintf(out->why, sizeof out->why, "command '%.400s'", got);
            goto done;
        }
    }
    for (size_t i = 0; i < h->nkeys; i++) {
        if (strcmp(h->keys[i].key, "INPUT") != 0)
            continue;
        const char *v = h->keys[i].value, *sp = strrchr(v, ' ');
        uint64_t want;
        if (!sp || sscanf(sp + 1, "xxh3:%" SCNx64, &want) != 1)
            continue;
        char in[4096];
        snprintf(in, sizeof in, "%s/%.*s", w->dir, (int)(sp - v), v);
        if ((sp - v == 1 && v[0] == '-') || stat(in, &sb) != 0)
            continue; /* a pipe, or missing: what makes it is judged on its own */
        uint64_t now;
        if (pm_prov_trailer(in, &now) != PM_OK || now != want) {
            out->verdict = PM_PROV_OTHER;
            snprintf(out->why, sizeof out->why, "input '%.*s' has changed", (int)(sp - v), v);
            snprintf(out->input, sizeof out->input, "%.*s", (int)(sp - v), v);
            goto done;
        }
    }
done:
    pm_reader_close(rd);
    return PM_OK;
}
