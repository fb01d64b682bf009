/* fuzz_gather.h: what simd-gather does with a photon map and a queries file once both are
 * read (common/photonmap/gather_stage.c): view them for the gather, then gather every query
 * with a fixed and, when the map has widths, a variable kernel width, in the scalar kernel
 * and the widest the CPU has. One thread: the fuzzer runs one input at a time. */
#ifndef PM_FUZZ_GATHER_H
#define PM_FUZZ_GATHER_H

#include <omp.h>
#include <stdio.h>
#include <stdlib.h>

#include "base/cpu.h"
#include "formats/formats.h"
#include "photonmap/gather.h"

/* A partner file the fuzzed one is gathered with: $name, else the golden file. */
static int fuzz_partner(const char *env, const char *golden, const pm_schema_t *schema, pm_table_t *t)
{
    const char *path = getenv(env) ? getenv(env) : golden;
    if (pm_table_read(path, schema, pm_schema_required(schema), t) != PM_OK) {
        fprintf(stderr, "fuzz: cannot read the partner file '%s' (run from the repository root or set %s)\n", path,
                env);
        abort();
    }
    omp_set_num_threads(1);
    return 1;
}

static void fuzz_gather(const pm_table_t *map, const pm_table_t *queries, const char *qpath)
{
    int variable = map->col[PM_MAP_WIDTH] != NULL;
    pm_gather_map_t m;
    if (pm_gather_map_init(&m, map, variable) != PM_OK)
        return;
    pm_gather_queries_t q;
    pm_material_t *mats = NULL;
    double *out = NULL;
    if (pm_gather_queries_init(&q, queries, qpath, &mats) == PM_OK &&
        (out = malloc((q.n ? q.n : 1) * 3 * sizeof *out)) != NULL) {
        pm_isa_t isas[2] = {PM_ISA_SCALAR, pm_cpu_best_isa()};
        for (int v = 0; v <= variable; v++)
            for (int i = 0; i < 2; i++) {
                pm_gather_params_t p = {
                    .radius = 0.25, .kernel = (pm_kernel_t)i, .variable = v, .normal_cos = 0.5f, .isa = isas[i]};
                pm_gather_stats_t st;
                (void)pm_gather_run(&m, &q, 0, q.n, &p, out, &st);
            }
    }
    free(out);
    free(mats);
    pm_gather_map_free(&m);
}

#endif
