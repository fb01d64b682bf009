/* pfm.c: the Portable Float Map reader (pfm.h), so that measure-error and error-vs-time take a
 * reference image written by another renderer. The header is read token by token; the pixels
 * are read in one block and turned from the file's byte order, bottom-to-top rows and scale
 * into top-to-bottom RGB doubles, each value checked. */
#include "image/pfm.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const channel_names[3] = {"R", "G", "B"};

int pm_pfm_magic(const unsigned char *head, size_t n)
{
    return n >= 3 && head[0] == 'P' && (head[1] == 'F' || head[1] == 'f') &&
           (head[2] == ' ' || head[2] == '\t' || head[2] == '\n' || head[2] == '\r');
}

static int is_space(int c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

/* The next header token (at most cap - 1 bytes) after any whitespace; the one whitespace
 * character that ends it is consumed, so that after the scale the pixels come next. 0 when
 * the file ends first or the token is too long. */
static int read_token(FILE *f, char *tok, size_t cap)
{
    int c;
    while ((c = fgetc(f)) != EOF && is_space(c))
        ;
    size_t n = 0;
    while (c != EOF && !is_space(c)) {
        if (n + 1 >= cap)
            return 0;
        tok[n++] = (char)c;
        c = fgetc(f);
    }
    tok[n] = '\0';
    return n > 0 && c != EOF;
}

/* A width or height: decimal digits only, 1 to PM_PFM_MAX_SIDE. */
static int parse_side(const char *s, uint32_t *out)
{
    if (!*s || strspn(s, "0123456789") != strlen(s) || strlen(s) > 6)
        return 0;
    unsigned long v = strtoul(s, NULL, 10);
    *out = (uint32_t)v;
    return v >= 1 && v <= PM_PFM_MAX_SIDE;
}

static pm_result_t read_pixels(FILE *f, const char *path, uint32_t w, uint32_t h, int nc, double scale, double *rgb)
{
    size_t row_bytes = (size_t)w * (size_t)nc * 4;
    unsigned char *row = malloc(row_bytes);
    if (!row)
        return pm_error_set(PM_ERR_NOMEM, "out of memory reading PFM image '%s': rows of %zu bytes", path, row_bytes);
    int little = scale < 0;
    double mag = fabs(scale);
    pm_result_t r = PM_OK;
    /* File row k is image row h - 1 - k: PFM stores the bottom row first. */
    for (uint32_t k = 0; k < h && r == PM_OK; k++) {
        size_t got = fread(row, 1, row_bytes, f);
        if (got != row_bytes) {
            if (ferror(f))
                r = pm_error_set(pm_result_of_errno(errno), "cannot read PFM image '%s': %s", path, strerror(errno));
            else
                r = pm_error_set(PM_ERR_INPUT,
                                 "truncated PFM image '%s': %zu of %zu bytes of pixels (%" PRIu32 "x%" PRIu32
                                 ", %d channel%s)",
                                 path, (size_t)k * row_bytes + got, row_bytes * h, w, h, nc, nc == 1 ? "" : "s");
            break;
        }
        uint32_t y = h - 1 - k;
        for (uint32_t x = 0; x < w && r == PM_OK; x++)
            for (int c = 0; c < nc; c++) {
                const unsigned char *b = row + 4 * ((size_t)x * (size_t)nc + (size_t)c);
                uint32_t u = little
                                 ? (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24
                                 : (uint32_t)b[3] | (uint32_t)b[2] << 8 | (uint32_t)b[1] << 16 | (uint32_t)b[0] << 24;
                float v;
                memcpy(&v, &u, sizeof v);
                double d = (double)v * mag;
                if (!isfinite(d) || d < 0) {
                    r = pm_error_set(PM_ERR_INPUT,
                                     "PFM image '%s' pixel (%" PRIu32 ", %" PRIu32 ") channel %s is %g: radiance must "
                                     "be finite and not negative",
                                     path, x, y, nc == 1 ? "Y" : channel_names[c], d);
                    break;
                }
                double *px = rgb + 3 * ((size_t)y * w + x);
                if (nc == 1)
                    px[0] = px[1] = px[2] = d;
                else
                    px[c] = d;
            }
    }
    free(row);
    return r;
}

pm_result_t pm_pfm_read(const char *path, uint32_t *w_out, uint32_t *h_out, int *channels_out, double **rgb_out)
{
    *rgb_out = NULL;
    *w_out = *h_out = 0;
    *channels_out = 0;
    FILE *f = fopen(path, "rb");
    if (!f) /* a missing file is the user's input, as the pmtk reader classes it */
        return pm_error_set(pm_result_of_errno(errno), "cannot open '%s': %s", path, strerror(errno));
    unsigned char magic[3];
    char tw[16], th[16], ts[64];
    uint32_t w = 0, h = 0;
    pm_result_t r = PM_OK;
    double *rgb = NULL;
    size_t n = fread(magic, 1, 3, f);
    if (!pm_pfm_magic(magic, n)) {
        r = pm_error_set(PM_ERR_INPUT, "'%s' is not a PFM image: it does not start with 'PF' or 'Pf'", path);
        goto done;
    }
    int nc = magic[1] == 'F' ? 3 : 1;
    /* The magic's whitespace is read; the header's three tokens follow. */
    if (!read_token(f, tw, sizeof tw) || !read_token(f, th, sizeof th) || !read_token(f, ts, sizeof ts)) {
        r = pm_error_set(PM_ERR_INPUT,
                         "PFM image '%s': the header ends early or holds an overlong word: expected "
                         "'%s', width, height and scale, each followed by whitespace",
                         path, nc == 3 ? "PF" : "Pf");
        goto done;
    }
    if (!parse_side(tw, &w) || !parse_side(th, &h)) {
        r = pm_error_set(PM_ERR_INPUT, "PFM image '%s': bad size '%s' x '%s': expected whole numbers from 1 to %u",
                         path, tw, th, PM_PFM_MAX_SIDE);
        goto done;
    }
    char *end;
    errno = 0;
    double scale = strtod(ts, &end);
    if (*end || errno || !isfinite(scale) || scale == 0) {
        r = pm_error_set(PM_ERR_INPUT,
                         "PFM image '%s': bad scale '%s': expected a finite number other than 0 (its sign gives the "
                         "byte order: negative little-endian, positive big-endian)",
                         path, ts);
        goto done;
    }
    size_t vals = (size_t)w * h * 3;
    if (!(rgb = malloc(vals * sizeof *rgb))) {
        r = pm_error_set(PM_ERR_NOMEM, "out of memory reading PFM image '%s': %" PRIu32 "x%" PRIu32 " pixels", path, w,
                         h);
        goto done;
    }
    if ((r = read_pixels(f, path, w, h, nc, scale, rgb)) != PM_OK)
        goto done;
    long extra = 0;
    while (fgetc(f) != EOF)
        extra++;
    if (ferror(f)) {
        r = pm_error_set(pm_result_of_errno(errno), "cannot read PFM image '%s': %s", path, strerror(errno));
        goto done;
    }
    if (extra) {
        r = pm_error_set(PM_ERR_INPUT,
                         "PFM image '%s': %ld bytes after the last pixel of %" PRIu32 "x%" PRIu32 " (%d channel%s): "
                         "the header's size does not match the data",
                         path, extra, w, h, nc, nc == 1 ? "" : "s");
        goto done;
    }
    *w_out = w, *h_out = h, *channels_out = nc;
    *rgb_out = rgb;
    rgb = NULL;
done:
    free(rgb);
    fclose(f);
    return r;
}
