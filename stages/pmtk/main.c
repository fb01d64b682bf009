/* pmtk: one command for every program, git style: `pmtk composite ARGS...` runs pmtk's composite
 * with ARGS, whatever else is on the PATH (ImageMagick installs a /usr/bin/composite).
 *
 * The programs are looked for in one folder: $PMTK_EXEC_PATH when set; else PREFIX/libexec/pmtk
 * beside an installed pmtk (PREFIX/bin/pmtk, where `make install` puts them); else, in the build
 * tree, the folder this pmtk is in (bin/). The program is exec'd in place of this process, so
 * its exit status and signals are the caller's. `pmtk` alone or `pmtk --help` lists them.
 * Exit: 2 for an unknown command or option, 3 when the program cannot be started. */
#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/version.h"

/* The folder of the programs into dir (PATH_MAX bytes); 0 when none is found. */
static int exec_dir(char *dir)
{
    const char *env = getenv("PMTK_EXEC_PATH");
    if (env && *env) {
        snprintf(dir, PATH_MAX, "%s", env);
        return 1;
    }
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0)
        return 0;
    self[n] = '\0';
    char *slash = strrchr(self, '/');
    if (!slash)
        return 0;
    *slash = '\0';
    struct stat sb;
    snprintf(dir, PATH_MAX, "%s/../libexec/pmtk", self);
    if (stat(dir, &sb) == 0 && S_ISDIR(sb.st_mode))
        return 1;
    snprintf(dir, PATH_MAX, "%s", self);
    return 1;
}

/* A program name: lower-case letters, digits and '-', not starting with '-', not pmtk itself. */
static int valid_name(const char *s)
{
    if (!*s || *s == '-' || strcmp(s, "pmtk") == 0 || strlen(s) > 64)
        return 0;
    for (; *s; s++)
        if (!((*s >= 'a' && *s <= 'z') || (*s >= '0' && *s <= '9') || *s == '-'))
            return 0;
    return 1;
}

static int by_name(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* Prints the usage and the programs of dir, sorted. */
static void usage(FILE *f, const char *dir)
{
    fprintf(f, "usage: pmtk COMMAND [ARGS...]\n"
               "Run the pmtk program COMMAND with ARGS (pmtk COMMAND --help for its options).\n\n"
               "commands:\n");
    DIR *d = dir ? opendir(dir) : NULL;
    char *names[256];
    size_t n = 0;
    for (struct dirent *e; d && (e = readdir(d)) && n < 256;) {
        char path[PATH_MAX];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (valid_name(e->d_name) && access(path, X_OK) == 0 && (names[n] = strdup(e->d_name)))
            n++;
    }
    if (d)
        closedir(d);
    qsort(names, n, sizeof *names, by_name);
    for (size_t i = 0; i < n; i++) {
        fprintf(f, "  %s\n", names[i]);
        free(names[i]);
    }
    fprintf(f, "\noptions:\n  -h, --help     print this and exit\n      --version  print the version and exit\n");
}

int main(int argc, char **argv)
{
    char dir[PATH_MAX];
    int have_dir = exec_dir(dir);
    if (argc < 2 || strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 || strcmp(argv[1], "help") == 0) {
        if (argc >= 3 && strcmp(argv[1], "help") == 0 && valid_name(argv[2])) {
            /* `pmtk help composite` is `pmtk composite --help` */
            char *args[] = {argv[0], argv[2], "--help", NULL};
            return main(3, args);
        }
        usage(argc < 2 ? stderr : stdout, have_dir ? dir : NULL);
        return argc < 2 ? 2 : 0;
    }
    if (strcmp(argv[1], "--version") == 0) {
        printf("pmtk (pmtk) %s\n", PM_VERSION_STRING);
        return 0;
    }
    if (!valid_name(argv[1])) {
        fprintf(stderr, "pmtk: unknown command '%s' (usage error)\n", argv[1]);
        fprintf(stderr, "usage: pmtk COMMAND [ARGS...] (pmtk --help lists the commands)\n");
        return 2;
    }
    if (!have_dir) {
        fprintf(stderr, "pmtk: cannot find the folder of pmtk's programs: set PMTK_EXEC_PATH (system error)\n");
        return 3;
    }
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/%s", dir, argv[1]);
    if (access(path, X_OK) != 0) {
        int e = errno;
        if (e == ENOENT) {
            fprintf(stderr, "pmtk: unknown command '%s': no program '%s' (usage error)\n", argv[1], path);
            fprintf(stderr, "usage: pmtk COMMAND [ARGS...] (pmtk --help lists the commands)\n");
            return 2;
        }
        fprintf(stderr, "pmtk: cannot run '%s': %s (system error)\n", path, strerror(e));
        return 3;
    }
    argv[1] = path;
    execv(path, argv + 1);
    fprintf(stderr, "pmtk: cannot run '%s': %s (system error)\n", path, strerror(errno));
    return 3;
}
