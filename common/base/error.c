/* error.c: the thread-local error message behind pm_error_set, and the slots that carry one
 * out of a parallel region. */
#include "base/error.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

static _Thread_local char pm_error_buf[PM_ERROR_MAX];

static void pm_error_sanitize(char *s)
{
    /* One line, always: a path or a value with a newline must not split the message. */
    for (; *s; s++)
        if (*s == '\n' || *s == '\r')
            *s = ' ';
}

pm_result_t pm_error_set(pm_result_t code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(pm_error_buf, sizeof pm_error_buf, fmt, ap);
    va_end(ap);
    pm_error_sanitize(pm_error_buf);
    return code;
}

const char *pm_error_message(void) { return pm_error_buf; }

void pm_error_prefix(const char *fmt, ...)
{
    char prefix[PM_ERROR_MAX], old[PM_ERROR_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(prefix, sizeof prefix, fmt, ap);
    va_end(ap);
    memcpy(old, pm_error_buf, sizeof old);
    /* Cut the prefix first so the message it introduces keeps as much as it can. */
    int n = (int)strnlen(prefix, PM_ERROR_MAX / 2);
    snprintf(pm_error_buf, sizeof pm_error_buf, "%.*s: %.*s", n, prefix, PM_ERROR_MAX - n - 3, old);
    pm_error_sanitize(pm_error_buf);
}

const char *pm_result_string(pm_result_t code)
{
    switch (code) {
    case PM_OK: return "ok";
    case PM_ERR_USAGE: return "usage";
    case PM_ERR_INPUT: return "input";
    case PM_ERR_IO: return "io";
    case PM_ERR_NOMEM: return "nomem";
    case PM_ERR_INTERNAL: return "internal";
    default: return "unknown";
    }
}

int pm_result_exit_code(pm_result_t code)
{
    /* The numbers of docs/cli.md's table; the enum's values are not exit statuses (PM_ERR_USAGE
     * is 1, its status 2), so that the table can change without renumbering the library. */
    switch (code) {
    case PM_OK: return 0;
    case PM_ERR_INPUT: return 1;
    case PM_ERR_USAGE: return 2;
    case PM_ERR_IO:
    case PM_ERR_NOMEM: return 3;
    default: return 4; /* PM_ERR_INTERNAL, and a code nobody defined: a bug either way */
    }
}

pm_result_t pm_result_of_errno(int e)
{
    switch (e) {
    case ENOENT:
    case ENOTDIR:
    case EISDIR:
    case ELOOP:
    case ENAMETOOLONG:
    case EACCES:
    case EPERM:
    case EROFS:
    case ENXIO:
    case ENODEV:
    case EBADF: return PM_ERR_INPUT;
    case ENOMEM: return PM_ERR_NOMEM;
    default: return PM_ERR_IO;
    }
}

void pm_error_slot_init(pm_error_slot_t *slot)
{
    slot->code = PM_OK;
    slot->task = UINT64_MAX;
    slot->message[0] = '\0';
}

pm_result_t pm_error_slot_record(pm_error_slot_t *slot, uint64_t task, pm_result_t code)
{
    if (code == PM_OK)
        return code;
        /* A named critical section: OpenMP's, since every parallel region in pmtk is OpenMP's. */
#pragma omp critical(pm_error_slot)
    {
        if (slot->code == PM_OK || task < slot->task) {
            slot->code = code;
            slot->task = task;
            memcpy(slot->message, pm_error_buf, sizeof slot->message);
        }
    }
    return code;
}

pm_result_t pm_error_slot_raise(const pm_error_slot_t *slot)
{
    if (slot->code != PM_OK)
        memcpy(pm_error_buf, slot->message, sizeof pm_error_buf);
    return slot->code;
}
