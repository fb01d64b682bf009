/* error.h: result codes and the per-thread error message of the pmtk library.
 *
 * Library functions never exit: they return a pm_result_t and, on failure, leave
 * a one-line message naming the subject and the values in a thread-local buffer
 * (pm_error_message). Only a stage's main decides the exit status, by class
 * (pm_result_exit_code: 1 input, 2 usage, 3 io or nomem, 4 internal), so that a caller can
 * retry what the system failed and not what the data or the command line got wrong; the
 * class's name (pm_result_string) ends the printed message and is error.class in --stats
 * (see docs/cli.md, "Exit status and errors"). */
#ifndef PM_ERROR_H
#define PM_ERROR_H

#include <stdint.h>

typedef int32_t pm_result_t;

enum {
    PM_OK = 0,
    PM_ERR_USAGE = 1,   /* bad command line: unknown option, bad number, missing argument */
    PM_ERR_INPUT = 2,   /* bad input data: malformed file, scene, value out of range */
    PM_ERR_IO = 3,      /* the system failed us: open, read, write, rename */
    PM_ERR_NOMEM = 4,   /* an allocation failed */
    PM_ERR_INTERNAL = 5 /* a bug in pmtk: an invariant did not hold */
};

/* Sets the thread's message (printf-style) and returns code, so that
 * `return pm_error_set(PM_ERR_INPUT, "...", ...)` reads as one statement. */
pm_result_t pm_error_set(pm_result_t code, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* The message of the last failure on this thread ("" when none). */
const char *pm_error_message(void);

/* Prefixes the current message with "prefix: " (for adding a file name upstream). */
void pm_error_prefix(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* Messages are one line of at most this many bytes (longer ones are cut). */
#define PM_ERROR_MAX 1024

/* An error raised inside a parallel region, kept for the thread that started it. The
 * message behind pm_error_set is thread-local, so one set on an OpenMP worker never reaches
 * the caller: a task that fails records its code and message here (pm_error_slot_record,
 * safe from any thread), and after the region the caller re-raises it on its own thread
 * (pm_error_slot_raise). Of several failures the lowest task index wins, so the message
 * is the same for any thread count. */
typedef struct {
    pm_result_t code; /* PM_OK while no task failed */
    uint64_t task;    /* index of the failed task that is kept */
    char message[PM_ERROR_MAX];
} pm_error_slot_t;

void pm_error_slot_init(pm_error_slot_t *slot);

/* Records task's failure with the calling thread's current message, unless a task of a
 * lower index already failed. Returns code, so a worker can `return` through it. */
pm_result_t pm_error_slot_record(pm_error_slot_t *slot, uint64_t task, pm_result_t code);

/* On the thread that reports: makes the recorded message this thread's and returns the
 * recorded code (PM_OK, message untouched, when no task failed). */
pm_result_t pm_error_slot_raise(const pm_error_slot_t *slot);

/* A short name of a result code: "ok", "usage", "input", "io", "nomem", "internal". */
const char *pm_result_string(pm_result_t code);

/* Exit status for a result code: 0 ok, 1 input, 2 usage, 3 io and nomem (the system failed:
 * a retry may succeed), 4 internal and any code not in the enum (a bug). */
int pm_result_exit_code(pm_result_t code);

/* The class of a failed system call on a path or a descriptor the user gave, from its errno
 * e. What a retry cannot fix is the user's input, PM_ERR_INPUT: the path is wrong or not
 * theirs to use (ENOENT, ENOTDIR, EISDIR, ELOOP, ENAMETOOLONG, EACCES, EPERM, EROFS, ENXIO,
 * ENODEV, EBADF). ENOMEM is PM_ERR_NOMEM. Everything else is PM_ERR_IO: the
 * system failed, and the same command may succeed later or elsewhere (EIO, ENOSPC, EDQUOT,
 * EFBIG, EMFILE, ENFILE, EAGAIN, EINTR, ESTALE, ETIMEDOUT, and errnos not listed). Use it
 * with the errno of the call that failed, before anything else can change errno. */
pm_result_t pm_result_of_errno(int e);

#endif
