/* passplan.c: the passes a resident tracer runs, from --passes A:B or a --plan read line by
 * line as a driver writes it (see passplan.h). */
#include "base/passplan.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/args.h"
#include "base/timer.h"

pm_result_t pm_passplan_open(pm_passplan_t *pp, const char *range, const char *plan)
{
    memset(pp, 0, sizeof *pp);
    pp->last = -1;
    if ((range != NULL) == (plan != NULL))
        return pm_error_set(PM_ERR_USAGE, "give one of --passes A:B and --plan FILE");
    if (range) {
        const char *colon = strchr(range, ':');
        char a[32];
        int64_t first = 0, last = 0;
        if (!colon || (size_t)(colon - range) >= sizeof a)
            return pm_error_set(PM_ERR_USAGE, "--passes '%s': expected A:B, passes 1 <= A <= B", range);
        memcpy(a, range, (size_t)(colon - range));
        a[colon - range] = 0;
        if (pm_parse_i64(a, &first) != PM_OK || pm_parse_i64(colon + 1, &last) != PM_OK || first < 1 || last < first)
            return pm_error_set(PM_ERR_USAGE, "--passes '%s': expected A:B, passes 1 <= A <= B", range);
        pp->first = pp->next = first;
        pp->last = last;
        return PM_OK;
    }
    pp->path = strcmp(plan, "-") ? plan : "stdin";
    pp->plan = strcmp(plan, "-") ? fopen(plan, "r") : stdin;
    if (!pp->plan)
        return pm_error_set(PM_ERR_INPUT, "cannot open the plan '%s': %s", plan, strerror(errno));
    return PM_OK;
}

pm_result_t pm_passplan_next(pm_passplan_t *pp, int64_t *pass_out, int64_t *size_out, int *end_out)
{
    *pass_out = 0, *size_out = 0, *end_out = 0;
    if (!pp->plan) {
        if (pp->next > pp->last) {
            *end_out = 1;
            return PM_OK;
        }
        *pass_out = pp->next++;
        return PM_OK;
    }
    char buf[256];
    while (fgets(buf, sizeof buf, pp->plan)) {
        pp->line++;
        size_t len = strlen(buf);
        if (len == sizeof buf - 1 && buf[len - 1] != '\n')
            return pm_error_set(PM_ERR_INPUT, "plan '%s' line %" PRId64 ": longer than %zu bytes", pp->path, pp->line,
                                sizeof buf - 2);
        char *save = NULL, *w1 = strtok_r(buf, " \t\r\n", &save);
        if (!w1 || w1[0] == '#')
            continue;
        char *w2 = strtok_r(NULL, " \t\r\n", &save), *w3 = strtok_r(NULL, " \t\r\n", &save);
        int64_t pass = 0, size = 0;
        if (w3 || pm_parse_i64(w1, &pass) != PM_OK || pass < 1 ||
            (w2 && (pm_parse_i64(w2, &size) != PM_OK || size < 1)))
            return pm_error_set(PM_ERR_INPUT,
                                "plan '%s' line %" PRId64 ": expected 'PASS [SIZE]', a pass of at least 1 and a size "
                                "of at least 1",
                                pp->path, pp->line);
        *pass_out = pass, *size_out = size;
        return PM_OK;
    }
    if (ferror(pp->plan))
        return pm_error_set(PM_ERR_IO, "cannot read the plan '%s': %s", pp->path, strerror(errno));
    *end_out = 1;
    return PM_OK;
}

int pm_passplan_single(const pm_passplan_t *pp) { return !pp->plan && pp->first == pp->last; }

void pm_passplan_close(pm_passplan_t *pp)
{
    if (pp->plan && pp->plan != stdin)
        fclose(pp->plan);
    pp->plan = NULL;
}

pm_result_t pm_passplan_tell_ready(const pm_passplan_t *pp, pm_stage_t *st)
{
    if (!pp->ready)
        return PM_OK;
    double wall = pm_timer_wall(&st->timer), cpu = pm_time_cpu();
    pm_stage_stat_double(st, "ready_s", wall);
    pm_stage_stat_double(st, "ready_cpu_s", cpu);
    char line[128];
    int n = snprintf(line, sizeof line, "%s ready %.6f %.6f\n", st->name, wall, cpu);
    /* one write of less than PIPE_BUF bytes: whole on a pipe that other stages write too */
    int fd = open(pp->ready, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0)
        return pm_error_set(pm_result_of_errno(errno), "cannot open --ready '%s': %s", pp->ready, strerror(errno));
    ssize_t w = write(fd, line, (size_t)n);
    int e = errno;
    close(fd);
    if (w != n)
        return pm_error_set(w < 0 ? pm_result_of_errno(e) : PM_ERR_IO, "cannot write --ready '%s': %s", pp->ready,
                            w < 0 ? strerror(e) : "short write");
    return PM_OK;
}

pm_result_t pm_passplan_run(pm_passplan_t *pp, pm_stage_t *st, char **argv, const void *const *drop, size_t ndrop,
                            const char *size_opt, int64_t max_size, pm_passplan_fn fn, void *user)
{
    int argc0 = st->argc, done = 0;
    char **argv0 = st->argv;
    double cpu = 0.0;
    pm_result_t r = pm_passplan_tell_ready(pp, st);
    while (r == PM_OK) {
        int64_t pass, size;
        int end;
        if ((r = pm_passplan_next(pp, &pass, &size, &end)) != PM_OK || end)
            break;
        if (size > max_size) {
            r = pm_error_set(PM_ERR_INPUT, "plan '%s' line %" PRId64 ": %s %" PRId64 " is above %" PRId64, pp->path,
                             pp->line, size_opt, size, max_size);
            break;
        }
        char pw[32], nw[32];
        snprintf(pw, sizeof pw, "%" PRId64, pass);
        snprintf(nw, sizeof nw, "%" PRId64, size);
        char *add[] = {"--pass", pw, (char *)size_opt, nw};
        char **v = NULL;
        if ((r = pm_stage_pass_command(st, argv, drop, size ? ndrop : ndrop - 1, add, size ? 4 : 2, &st->argc, &v)) !=
            PM_OK)
            break;
        st->argv = v;
        double c0 = pm_time_cpu();
        r = fn(user, pass, size);
        cpu += pm_time_cpu() - c0;
        st->argc = argc0, st->argv = argv0;
        free(v);
        if (r != PM_OK) {
            char name[64];
            snprintf(name, sizeof name, "pass %" PRId64, pass);
            r = pm_stage_frame_error(r, done, name);
            break;
        }
        done++;
    }
    if (r == PM_OK && done == 0)
        r = pm_error_set(PM_ERR_INPUT, "the plan '%s' names no pass", pp->path ? pp->path : "");
    pm_stage_stat_int(st, "passes", done);
    pm_stage_stat_double(st, "pass_cpu_s", cpu);
    return r;
}
