/* pm-frames: a camera (or point-light) path rendered as a sequence of frames through the stage
 * programs, as in the paper's interactive session; pipelines/frames is this program under another
 * name (docs/pipelines.md, "Frames"; common/engine/frames.c).
 *
 *   pm-frames SCENE OUTDIR [NAME=VALUE ...]
 *
 * Writes OUTDIR/scene-NNNN.json, OUTDIR/frame-NNNN.exr and .png, frames.json, and with resident
 * stages (STREAM=1) each stage's --stats in OUTDIR/stats/. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/memory.h"
#include "base/stage.h"
#include "base/timer.h"
#include "engine/engine.h"

static const char *const param_help =
    "Parameters:\n"
    "  FRAMES=8          frames\n"
    "  MOVE=camera       camera: the eye orbits the look-at point; light: point lights move\n"
    "  DEGREES=30        camera: the orbit's total angle about the up axis, centred on the scene's eye\n"
    "  SHIFT=0.1         light: total distance (m) the point lights move along x\n"
    "  PHOTONS= SPP= WIDTH= HEIGHT= RADIUS= K= ORDER=hilbert  the stages' options (empty: the scene's)\n"
    "  PRIMARY= PIXEL=   trace-gather-points' --primary and --pixel (PIXEL=center: through the centres)\n"
    "  THREADS=          every stage's --threads\n"
    "  PNG=1             write a PNG per frame (0: EXR only)\n"
    "  QUIET=1           no progress line on a terminal\n"
    "  STREAM=1          resident stages and one pipeline (0: every stage per frame)\n"
    "  REUSE=1           MOVE=camera: trace the photons once and keep the map (0: every frame)\n"
    "  OVERLAP=1         STREAM=0: the photon side and the eye side at the same time (0: one after the other)\n"
    "  MODE=gather       direct-vis: the queries are the primary hits; the image is the map's estimate alone\n"
    "  SECONDARY_DIRECT=0  1: the gather points sample the lights, the map leaves out their first hits\n"
    "  DIFFUSE_DEPTH=0   1 or 2: Lambertian bounces a secondary path takes before it gathers\n"
    "Prints one line per frame and the frames per second; writes OUTDIR/frames.json. One run at a time\n"
    "holds OUTDIR (OUTDIR/.lock). Exit status: 0 ok, 1 bad input or a stage failed on it (or OUTDIR is\n"
    "held), 2 bad usage, 3 I/O or out of memory, 4 internal.\n";

static pm_stage_t stage_at_exit;
static void free_stage_args(void) { pm_args_free(&stage_at_exit.args); }

int main(int argc, char **argv)
{
    /* malloc on huge pages, for this driver and every stage it starts */
    pm_memory_huge_malloc(argv, pm_time_wall());
    (void)pm_memory_started(pm_time_wall()); /* takes PMTK_START_S out of the environment */
    const char *base = strrchr(argv[0], '/');
    base = base ? base + 1 : argv[0];
    /* as pipelines/frames (exec -a), messages start "frames:" as that driver's always did */
    const char *me = strcmp(base, "frames") == 0 ? "frames" : "pm-frames";
    pm_stage_t *st = &stage_at_exit;
    pm_stage_defaults(st);
    const pm_option_t opts[] = {PM_STAGE_COMMON_OPTIONS(*st), {0}};
    const pm_cli_t cli = {.program = "pm-frames",
                          .synopsis = "[options] SCENE OUTDIR [NAME=VALUE ...]",
                          .summary = "render a camera or point-light path as frames through the stage programs, "
                                     "resident on streams of documents; frames per second",
                          .options = opts,
                          .min_args = 2,
                          .max_args = -1};
    int rc = pm_stage_begin(st, &cli, argc, argv);
    atexit(free_stage_args);
    if (rc >= 0) {
        if (st->help)
            fputs(param_help, stdout);
        return rc;
    }
    char bin[PATH_MAX];
    if (pm_engine_bin(bin, sizeof bin) != PM_OK) {
        fprintf(stderr, "%s: %s\n", me, pm_error_message());
        return 2;
    }
    char cmdline[8192] = "";
    for (int i = 0; i < argc; i++) {
        size_t n = strlen(cmdline);
        snprintf(cmdline + n, sizeof cmdline - n, "%s%s", i ? " " : "", argv[i]);
    }
    return pm_frames_run(me, st->args.args[0], st->args.args[1], st->args.nargs - 2, st->args.args + 2, bin, cmdline);
}
