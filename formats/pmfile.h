/* pmfile.h: the container every pmtk file uses (docs/formats.md is the byte-level spec).
 *
 *   "#?PMTK\n", then KEY=VALUE lines (format, version, count, record size, channels,
 *   scene bounds, provenance), then a blank line; a 4-byte byte-order marker; COUNT
 *   records of RECORD_SIZE bytes, little-endian, each the present channels packed in
 *   schema order; an 8-byte XXH3-64 of every byte before it.
 *
 * A format is a schema: its name, version and channel table. In memory a file is a
 * pm_table_t holding one array per present channel (structure of arrays, so that
 * hot and cold data live apart); absent optional channels are NULL and cost nothing. */
#ifndef PM_PMFILE_H
#define PM_PMFILE_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "base/error.h"

#define PM_MAGIC "#?PMTK"
#define PM_MAX_CHANNELS 16
#define PM_HEADER_MAX (1u << 20)      /* bytes of header text a reader accepts */
#define PM_HEADER_LINE_MAX (1u << 16) /* bytes of one header line */
#define PM_COUNT_MAX (1ull << 40)     /* records; anything above is a corrupt count */
#define PM_COMMAND_MAX 4096           /* bytes of a COMMAND line; longer ones end in " ..." */

typedef enum { PM_TYPE_U16, PM_TYPE_U32, PM_TYPE_F32, PM_TYPE_F64 } pm_type_t;

/* What a reader checks of every value of a channel. */
enum {
    PM_CH_REQUIRED = 1u << 0, /* every file of the format has it */
    PM_CH_FINITE = 1u << 1,   /* no NaN or Inf */
    PM_CH_NONNEG = 1u << 2,   /* >= 0 (implies finite) */
    PM_CH_UNIT = 1u << 3,     /* a unit vector, length within 1e-3 of 1 */
    PM_CH_POSITIVE = 1u << 4  /* > 0 (implies finite) */
};

typedef struct {
    const char *name; /* "position" */
    pm_type_t type;
    unsigned components; /* 3 for a vector or RGB */
    unsigned flags;      /* PM_CH_* */
    const char *unit;    /* "m", "W", "1" */
    const char *doc;     /* one line for docs and pm-info */
} pm_channel_t;

typedef struct pm_table pm_table_t;
typedef struct pm_header pm_header_t;

/* The container's versions. Major 1 headers say their channels twice, as CHANNELS (names)
 * and CHANNEL_MASK (bits); from major 2 on CHANNELS alone says them. Readers still read
 * major 1 files, and check that the two keys agree; writers write the schema's version. */
#define PM_MAJOR_WITH_MASK 1 /* the last major version whose headers carry CHANNEL_MASK */

typedef struct {
    const char *name;      /* FORMAT value: "photons" */
    unsigned major, minor; /* the version this code writes, and the newest it reads */
    unsigned oldest_major; /* the oldest major version it still reads */
    const char *title;     /* "photons file", used in messages */
    const pm_channel_t *channels;
    unsigned nchannels;
    /* Checks the format's own header keys once the header is read (may be NULL). */
    pm_result_t (*validate_header)(const pm_header_t *h, const char *path);
    /* Checks raw records against the header (indices in range, ...), on every chunk a
     * reader reads or a writer writes, so ranges and streams are checked too (may be NULL). */
    pm_result_t (*validate_records)(const pm_header_t *h, const char *path, const unsigned char *rec, uint64_t n,
                                    uint64_t first);
    /* Checks relations across records once all are read (may be NULL). */
    pm_result_t (*validate_table)(const pm_table_t *t, const char *path);
} pm_schema_t;

typedef struct {
    char *key;
    char *value;
} pm_kv_t;

struct pm_header {
    const pm_schema_t *schema;
    unsigned major, minor; /* as read; a writer always writes the schema's */
    uint64_t count;        /* records */
    uint32_t channels;     /* bit i set: channel i of the schema is present */
    uint32_t record_size;  /* bytes */
    float bounds[6];       /* scene bounds: min x y z, max x y z, in scene units (m) */
    char **commands;       /* COMMAND lines, oldest first: the pipeline that made the file */
    size_t ncommands;
    pm_kv_t *keys; /* every other key, in file order (INPUT, SCENE, format keys) */
    size_t nkeys;
};

/* A table read from a file holds that file's header as read (INPUT lines included); a
 * stage writing a derived file starts a new header and takes provenance over with
 * pm_header_inherit (and pm_header_copy_keys for a same-format pass-through). */
struct pm_table {
    pm_header_t hdr;
    uint64_t count;             /* records held (== hdr.count) */
    void *col[PM_MAX_CHANNELS]; /* channel i: count * components values of its type */
    uint64_t checksum;          /* XXH3-64 of the file as read (its content hash) */
};

/* ---- schemas ---- */
size_t pm_type_size(pm_type_t t);
/* Record size in bytes of the channels in mask. */
uint32_t pm_schema_record_size(const pm_schema_t *s, uint32_t mask);
/* Byte offset of channel `channel` within a record of the channels in mask. */
uint32_t pm_schema_offset(const pm_schema_t *s, uint32_t mask, unsigned channel);
/* Mask of the schema's required channels. */
uint32_t pm_schema_required(const pm_schema_t *s);
/* The schema whose FORMAT is name, from every format pmtk knows; NULL if none. */
const pm_schema_t *pm_schema_find(const char *name);
/* Every known schema, NULL-terminated. */
const pm_schema_t *const *pm_schema_all(void);

/* ---- headers ---- */
void pm_header_init(pm_header_t *h, const pm_schema_t *s);
void pm_header_free(pm_header_t *h);
/* Sets key (replacing its first occurrence) or, with add, appends another. */
pm_result_t pm_header_set(pm_header_t *h, const char *key, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
pm_result_t pm_header_add(pm_header_t *h, const char *key, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
/* The value of the first occurrence of key, or NULL. */
const char *pm_header_get(const pm_header_t *h, const char *key);
/* A decimal integer key: fails with a message naming path and key when missing or malformed. */
pm_result_t pm_header_get_u64(const pm_header_t *h, const char *path, const char *key, uint64_t *out);
/* Appends a COMMAND line made of argv, shell-quoted where needed. */
pm_result_t pm_header_add_command(pm_header_t *h, int argc, char *const *argv);
/* Appends src's COMMAND lines not already present, and src's SCENE when h has none; when
 * h's SCENE is of the same scene and names other parts (the map's photons, the queries'
 * view), the two are joined into one that names both (docs/formats.md, SCENE). */
/* 1 when two SCENE values are of the same scene: equal up to their parts ("NAME xxh3:HASH"
 * alike), so a map that names the photons' part and queries that name the view's match; a
 * key of the one-hash form matches only itself. */
int pm_scene_key_same_scene(const char *a, const char *b);

pm_result_t pm_header_inherit(pm_header_t *h, const pm_header_t *src);
/* Appends INPUT=<path> xxh3:<hash>. */
pm_result_t pm_header_add_input(pm_header_t *h, const char *path, uint64_t hash);
/* Copies every key of src that h lacks (the pass-on rule for same-format stages). */
pm_result_t pm_header_copy_keys(pm_header_t *h, const pm_header_t *src);
/* The header text as a writer writes it (malloc'd, NUL-terminated). */
pm_result_t pm_header_format(const pm_header_t *h, char **text_out, size_t *len_out);

/* ---- streaming reader ---- */
typedef struct pm_reader pm_reader_t;
/* Opens path ("-" is stdin) and reads and checks the header and byte-order marker.
 * schema NULL accepts any known format. need: channels the caller requires. */
pm_result_t pm_reader_open(const char *path, const pm_schema_t *schema, uint32_t need, pm_reader_t **out);
/* The same on a stream the caller opened and closes (after pm_reader_close); name is
 * what messages call it. */
pm_result_t pm_reader_open_stream(FILE *f, const char *name, const pm_schema_t *schema, uint32_t need,
                                  pm_reader_t **out);
/* The next document of a stream of documents (docs/formats.md, "Streams": whole pmtk files one
 * after another on one pipe or file, each with its own header and checksum) on f, which the
 * caller opened and closes. At the clean end of the stream (end of file where a document would
 * start) returns PM_OK with *out NULL. name is what messages call this document (say
 * "stdin, frame 3"). Its pm_reader_finish stops after the checksum, leaving f at the next. */
pm_result_t pm_reader_open_next(FILE *f, const char *name, const pm_schema_t *schema, uint32_t need, pm_reader_t **out);
/* The input of a stream of documents: the file path, or stdin for "-"; a one-line error
 * naming path when it cannot be opened. pm_stream_close closes it unless it is stdin (or NULL). */
pm_result_t pm_stream_open(const char *path, FILE **out);
void pm_stream_close(FILE *f);
/* What messages call document frame of the stream at path ("PATH, frame N", "stdin, frame N"),
 * into buf of size bytes; returns buf. */
const char *pm_stream_frame_name(char *buf, size_t size, const char *path, uint64_t frame);
/* Reads the next document of the stream f whole into memory, its header parsed and checked,
 * its records and checksum not (a reader of the copy checks them): *buf_out (malloc'd) holds
 * *len_out bytes, a pmtk file of its own; NULL and 0 at the clean end of the stream. For a
 * stage that must take a document off its pipe before it reads another input. */
pm_result_t pm_reader_take_next(FILE *f, const char *name, const pm_schema_t *schema, unsigned char **buf_out,
                                size_t *len_out);
const pm_header_t *pm_reader_header(const pm_reader_t *r);
/* The header text exactly as read, magic line to blank line. */
const char *pm_reader_header_text(const pm_reader_t *r);
/* Reads up to max raw records (RECORD_SIZE bytes each) and checks every value;
 * *got_out < max only at the end of the payload. */
pm_result_t pm_reader_read(pm_reader_t *r, void *records, uint64_t max, uint64_t *got_out);
/* After the last record: reads the checksum, compares it, and checks that nothing follows. */
pm_result_t pm_reader_finish(pm_reader_t *r, uint64_t *checksum_out);
void pm_reader_close(pm_reader_t *r);

/* ---- streaming writer ---- */
typedef struct pm_writer pm_writer_t;
/* For a stage that writes a stream of documents (one per frame) to an output given by the
 * option named option: PM_OK for stdout ("-", /dev/stdout), /dev/fd/N or an existing file that
 * is not a regular file or a folder (a FIFO, a device); a usage error for a regular file, which
 * each document would replace. */
pm_result_t pm_writer_check_stream(const char *option, const char *path);
/* Creates path ("-" is stdout) through a temporary file and writes the header. */
pm_result_t pm_writer_open(const char *path, const pm_header_t *h, pm_writer_t **out);
pm_result_t pm_writer_write(pm_writer_t *w, const void *records, uint64_t n);
/* As pm_writer_write, for records that a reader of this format has checked already and the
 * caller only reorders or copies (hilbert-sort): hashed and written, not checked again. */
pm_result_t pm_writer_write_checked(pm_writer_t *w, const void *records, uint64_t n);
/* Checks that COUNT records were written, writes the checksum, renames into place. Frees
 * the writer whether it succeeds or not (on failure the temporary file is removed). */
pm_result_t pm_writer_commit(pm_writer_t *w);
/* Removes the temporary file and frees the writer; instead of commit, never after it. */
void pm_writer_abort(pm_writer_t *w);

/* ---- whole tables ---- */
/* Allocates a table of count records with the given channels, zeroed. */
pm_result_t pm_table_alloc(pm_table_t *t, const pm_schema_t *s, uint32_t channels, uint64_t count);
/* Reads a whole file. need: channels the caller requires (a clear error names the first missing). */
pm_result_t pm_table_read(const char *path, const pm_schema_t *schema, uint32_t need, pm_table_t *out);
/* Reads records [begin, end) (end clipped to COUNT) but checks the whole file. */
pm_result_t pm_table_read_range(const char *path, const pm_schema_t *schema, uint32_t need, uint64_t begin,
                                uint64_t end, pm_table_t *out);
/* The same from an open reader whose records have not been read yet. */
pm_result_t pm_table_read_from(pm_reader_t *r, uint64_t begin, uint64_t end, pm_table_t *out);
/* A file read a chunk of rows at a time, for a stage that streams it (simd-gather): chunks_open
 * gives `out` the reader's header (COUNT, channels, every key) and columns for cap rows, no
 * record read yet; each chunks_read fills rows [0, out->count) with the next at most cap
 * records (record *first_out of the file first), checked as pm_table_read_from checks them, and
 * the call that finds no more ends the file (its checksum into out->checksum) with
 * out->count 0. Free with pm_table_free. */
pm_result_t pm_table_chunks_open(pm_reader_t *r, uint64_t cap, pm_table_t *out);
pm_result_t pm_table_chunks_read(pm_reader_t *r, pm_table_t *t, uint64_t cap, uint64_t *first_out);
/* Record i as RECORD_SIZE bytes in file layout. */
void pm_table_record(const pm_table_t *t, uint64_t i, void *record_out);
pm_result_t pm_table_write(const pm_table_t *t, const char *path);
void pm_table_free(pm_table_t *t);

#endif
