/* pm-info: prints the header of any pmtk file and, with --records, its records as text;
 * with --json, the header as one JSON object per file, for scripts (pipelines/render).
 *
 * Reads every byte and checks it (header, values, tree shape, checksum) before it
 * says "ok", so `pm-info FILE` is also the way to validate a cached intermediate. The work is
 * formats/describe.c's; this main parses options and hands it each file. */
#include <stdio.h>

#include "base/stage.h"
#include "formats/describe.h"

static pm_result_t run(pm_stage_t *st, const pm_describe_options_t *o)
{
    FILE *out;
    pm_result_t res = pm_stage_open_output(st, &out);
    int nfiles = st->args.nargs > 0 ? st->args.nargs : 1;
    for (int i = 0; i < nfiles && res == PM_OK; i++) {
        uint64_t n;
        res = pm_describe_file(out, st->args.nargs > 0 ? st->args.args[i] : "-", o, &n);
        st->items += n;
    }
    return res;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    pm_describe_options_t o = {.limit = -1};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"records", 'r', PM_OPT_FLAG, &o.records, NULL, "print every record as a line of text after the header", 1, 0,
         NULL},
        {"limit", 'n', PM_OPT_INT, &o.limit, "N", "print at most N records; -1 prints all", -1, 9e18, NULL},
        {"header", 0, PM_OPT_FLAG, &o.header_only, NULL, "print the header only; do not read or check the payload", 1,
         0, NULL},
        {"json", 0, PM_OPT_FLAG, &o.json, NULL,
         "print each file's header as a JSON object (after the check, with its checksum) instead of text", 1, 0, NULL},
        {0},
    };
    static const char about[] =
        "Print the header of pmtk files (photons, photonmap, queries, radiance), check every byte, "
        "and optionally print the records.";
    const pm_cli_t cli = {"pm-info", "[options] FILE...", about, options, 0, -1, NULL};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    return pm_stage_end(&st, run(&st, &o));
}
