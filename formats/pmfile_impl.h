/* pmfile_impl.h: what the files of the container (header.c, header_text.c, reader.c,
 * check.c, writer.c, table.c) share and nothing else sees: only those include it; the
 * public interface is formats/pmfile.h. */
#ifndef PM_PMFILE_IMPL_H
#define PM_PMFILE_IMPL_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <xxhash.h>
#if defined(__x86_64__)
/* libxxhash's run-time dispatch: XXH3 in AVX2 or AVX-512 where the CPU has them (4x the
 * SSE2 default here), the same hash. */
#include <xxh_x86dispatch.h>
#endif

#include "formats/pmfile.h"

_Static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "pmtk files are little-endian; port the codecs");
_Static_assert(sizeof(float) == 4 && sizeof(double) == 8, "IEEE binary32 and binary64 expected");

#define PM_CHUNK_RECORDS 4096 /* records per I/O and transposition step */

/* The byte-order marker: the 32-bit value 0x01020304 as written by a little-endian
 * writer (04 03 02 01). A big-endian file would show 01 02 03 04. */
extern const unsigned char pmfile_bom[4];

/* Widens the pipe behind fd to a few MiB when fd is one (best effort: the system's
 * pipe-max-size caps it, and anything else is left as it is), so that the stages of a pipe
 * hand each other records in fewer, larger reads and writes, with fewer switches between them. */
void pmfile_widen_pipe(int fd);

struct pm_reader {
    FILE *f;
    int own_file;
    char *path;
    pm_header_t hdr;
    XXH3_state_t *hash;
    uint64_t next;           /* index of the next record to read */
    uint64_t file_size;      /* bytes, when the input is a regular file; else 0 */
    uint64_t payload_offset; /* bytes before the first record */
    unsigned char *scratch;  /* one chunk of raw records for validation */
    char *raw;               /* the header text as read */
    int in_stream;           /* one document of a stream (pm_reader_open_next): more may follow it */
};

/* ---- header.c: the header model ---- */
/* Bytes of one value of channel c (all its components). */
size_t pmfile_channel_size(const pm_channel_t *c);
/* A character a header key may hold: [A-Za-z0-9_.-]. */
int pmfile_key_char_ok(int c);
/* 1 when k is a non-empty key of such characters. */
int pmfile_key_ok(const char *k);
/* Appends key=value (value malloc'd, taken over, freed on failure); refuses the
 * container's own keys and malformed ones. */
pm_result_t pmfile_kv_append(pm_header_t *h, const char *key, char *value_owned);
/* Appends a COMMAND line (malloc'd, taken over, freed on failure). */
pm_result_t pmfile_command_append(pm_header_t *h, char *cmd_owned);
/* The schema's title for messages, or "pmtk file" before the format is known. */
const char *pmfile_title(const pm_header_t *h);
/* A header number: decimal digits only, no leading zero, at most 19 digits; 0 if not. */
int pmfile_parse_decimal(const char *v, uint64_t *out);

/* ---- header_text.c: the header as text ---- */
/* Shows n bytes as printable text with \xNN escapes, into out of cap bytes. */
void pmfile_show_bytes(const unsigned char *b, size_t n, char *out, size_t cap);
/* Parses header text (magic line to blank line; cut into lines in place) into h, whose
 * schema is set from FORMAT: the structure, version, channels, record size, bounds and
 * the format's own rules. want: the schema expected (NULL: any); need: channels the
 * caller requires; path names the file in messages. */
pm_result_t pmfile_header_parse(pm_header_t *h, const char *path, char *text, const pm_schema_t *want, uint32_t need);

/* ---- check.c: the value checks ---- */
/* The exact check of n raw records from record index first, then the format's record
 * checks: the source of every message. */
pm_result_t pmfile_check_exact(const pm_header_t *h, const char *path, const unsigned char *rec, uint64_t n,
                               uint64_t first);
/* The fast pass over n raw records: 1 when some value might fail the exact check. */
int pmfile_records_suspect(const pm_header_t *h, const unsigned char *rec, uint64_t n);
/* The same over rows [at, at + n) of a table's columns. */
int pmfile_columns_suspect(const pm_table_t *t, uint64_t at, uint64_t n);
/* The checks once a fast pass has answered: the exact check when suspect, else only the
 * format's record checks. */
pm_result_t pmfile_check_after(const pm_header_t *h, const char *path, const unsigned char *rec, uint64_t n,
                               uint64_t first, int suspect);
/* The fast pass and then pmfile_check_after. */
pm_result_t pmfile_check_records(const pm_header_t *h, const char *path, const unsigned char *rec, uint64_t n,
                                 uint64_t first);

/* ---- reader.c, writer.c: what a table read or write uses beyond the public calls ---- */
/* pm_reader_read, with the value checks left to the caller when check is 0 (a table read
 * checks each chunk itself, on its columns, before it reads the next). */
pm_result_t pmfile_reader_read(pm_reader_t *r, void *records, uint64_t max, uint64_t *got_out, int check);
/* pm_writer_write; with t, the records are rows [t_at, t_at + n) of table t, whose columns
 * the fast pass of the checks reads instead of the records. */
pm_result_t pmfile_writer_write(pm_writer_t *w, const void *records, uint64_t n, const pm_table_t *t, uint64_t t_at);

#endif
