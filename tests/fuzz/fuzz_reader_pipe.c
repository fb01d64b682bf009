/* fuzz_reader_pipe.c: libFuzzer target for the readers on a pipe, where no file size
 * vouches for COUNT and the columns grow as records arrive (pm_table_read_range's
 * streaming path). A thread feeds the input into a pipe; the reader reads the other end. */
#include <pthread.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <unistd.h>

#include "formats/formats.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

typedef struct {
    int fd;
    const uint8_t *data;
    size_t size;
} feed_t;

static void *feed(void *arg)
{
    feed_t *f = arg;
    for (size_t off = 0; off < f->size;) {
        ssize_t n = write(f->fd, f->data + off, f->size - off);
        if (n <= 0)
            break; /* the reader stopped early and closed its end */
        off += (size_t)n;
    }
    close(f->fd);
    return NULL;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int once;
    if (!once++)
        signal(SIGPIPE, SIG_IGN); /* the feeder sees EPIPE when the reader stops early */
    int fds[2];
    if (pipe(fds) != 0)
        return 0;
    feed_t f = {fds[1], data, size};
    pthread_t t;
    if (pthread_create(&t, NULL, feed, &f) != 0) {
        close(fds[0]);
        close(fds[1]);
        return 0;
    }
    FILE *in = fdopen(fds[0], "rb");
    pm_reader_t *r;
    if (in && pm_reader_open_stream(in, "pipe", NULL, 0, &r) == PM_OK) {
        pm_table_t tab;
        if (pm_table_read_from(r, 0, UINT64_MAX, &tab) == PM_OK)
            pm_table_free(&tab);
        pm_reader_close(r);
    }
    if (in)
        fclose(in); /* a blocked writer now gets EPIPE and ends */
    else
        close(fds[0]);
    pthread_join(t, NULL);
    return 0;
}
