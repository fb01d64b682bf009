/* fuzz_file.h: the fuzz input as a file the readers open by path (they read files and
 * pipes, not memory), one per process. */
#ifndef PM_FUZZ_FILE_H
#define PM_FUZZ_FILE_H

#include <stdint.h>
#include <stdio.h>
#include <unistd.h>

/* Writes data to /tmp/pmtk-fuzz-<pid><suffix> and returns its name, or NULL. */
static const char *fuzz_write_file(const uint8_t *data, size_t size, const char *suffix)
{
    static char path[80];
    snprintf(path, sizeof path, "/tmp/pmtk-fuzz-%ld%s", (long)getpid(), suffix);
    FILE *f = fopen(path, "wb");
    if (!f)
        return NULL;
    size_t put = fwrite(data, 1, size, f);
    if (fclose(f) != 0 || put != size)
        return NULL;
    return path;
}

#endif
