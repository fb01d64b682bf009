/* describe.h: a pmtk file described for people and for scripts, the engine of pm-info.
 *
 * As text: the header as written, then (on request) one line per record with a column line
 * naming each component, then "# ok: N records, checksum xxh3:..." once every byte is checked.
 * As JSON: the header as one object, its structural keys typed, written only after the check
 * so that a reader of it sees a whole object or none (docs/programs/pm-info.md).
 *
 * Also the two JSON habits every describing program shares: strings enter JSON through one
 * door that turns a string that is not UTF-8 into an error naming it, and an object is written
 * indented, in insertion order, with floats to 9 significant digits. */
#ifndef PM_DESCRIBE_H
#define PM_DESCRIBE_H

#include <jansson.h>
#include <stdint.h>
#include <stdio.h>

#include "base/error.h"
#include "formats/pmfile.h"

typedef struct {
    int records;     /* print the records as text after the header */
    int64_t limit;   /* at most this many records; -1 all */
    int header_only; /* do not read or check the payload */
    int json;        /* the header as a JSON object instead of text (not with records) */
} pm_describe_options_t;

/* Describes the file at path ("-" is stdin) on out as o asks. *count_out becomes the number
 * of records checked (0 with header_only). A file that fails a check prints nothing more and
 * returns the reader's failure. */
pm_result_t pm_describe_file(FILE *out, const char *path, const pm_describe_options_t *o, uint64_t *count_out);

/* The header h (read from the file called name, whose header text is text) as a new JSON
 * object: file, format, version, byte_order, count, record_size, channels (names), bounds,
 * software, commands, inputs ({path, hash}), keys (every other key, a repeated one by its
 * first value). The caller owns *j_out. */
pm_result_t pm_describe_header_json(const char *name, const pm_header_t *h, const char *text, json_t **j_out);

/* Strings into JSON through one door that remembers the first that failed: JSON carries UTF-8
 * only, and a name in another encoding must be an error naming it, not a key left out. */
typedef struct {
    const char *failed; /* what the first string that could not be made was, or NULL */
    int nomem;          /* it failed for want of memory, not for its encoding */
} pm_json_strings_t;

/* The n bytes at s as a JSON string, or NULL (recorded in js under `what`, e.g. "COMMAND"). */
json_t *pm_json_stringn(pm_json_strings_t *js, const char *what, const char *s, size_t n);

/* Ends the building of j: on success hands it to *j_out; if a string failed (or j is NULL, as
 * jansson returns when memory is short) frees j and fails with "cannot describe SUBJECT as
 * JSON: WHAT is not UTF-8" (input) or "out of memory describing SUBJECT as JSON", SUBJECT
 * formatted from fmt. */
pm_result_t pm_json_strings_finish(const pm_json_strings_t *js, json_t *j, json_t **j_out, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

/* Writes j and a newline to out (indent 2, insertion order, floats to 9 digits) and frees j;
 * a failed write is "cannot write WHAT", WHAT formatted from fmt. */
pm_result_t pm_json_write(FILE *out, json_t *j, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

#endif
