/* transport.c: the tracers' names for the BSDF (calls into physics/bsdf.h, which defines every
 * kind once) and the triangles' front normals that every tracer shares (transport.h); the
 * lights are render/light.c's. */
#include "render/transport.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "math/sampling.h"

int pm_bsdf_sample(const pm_material_t *m, const float n[3], const float wo[3], float u, float u1, float u2,
                   float wi_out[3])
{
    if (m->kind == PM_MAT_STANDARD) {
        pm_lobe_t lobe = u < pm_bsdf_standard_diffuse_share(m) ? PM_LOBE_DIFFUSE : PM_LOBE_GLOSSY;
        return pm_bsdf_standard_sample_lobe(m, (int)lobe, n, wo, u1, u2, wi_out);
    }
    pm_bsdf_sample_t s;
    int ok = pm_bsdf_sample_wi(m, n, wo, u, u1, u2, PM_BSDF_RADIANCE, &s);
    memcpy(wi_out, s.wi, sizeof s.wi);
    return ok;
}

int pm_specular_sample(const pm_material_t *m, const float ng[3], const float wo[3], float u, int radiance,
                       float wi_out[3], float weight_out[3])
{
    pm_bsdf_sample_t s;
    /* u1, u2 are unused by delta lobes. */
    if (!pm_bsdf_is_delta(m) ||
        !pm_bsdf_sample_wi(m, ng, wo, u, 0.0f, 0.0f, radiance ? PM_BSDF_RADIANCE : PM_BSDF_IMPORTANCE, &s)) {
        for (int k = 0; k < 3; k++)
            wi_out[k] = weight_out[k] = 0.0f;
        return -1;
    }
    memcpy(wi_out, s.wi, sizeof s.wi);
    memcpy(weight_out, s.weight, sizeof s.weight);
    return (s.lobe & PM_BSDF_TRANSMIT) ? 1 : 0;
}

pm_result_t pm_shade_geom_init(const pm_scene_t *s, pm_shade_geom_t *g)
{
    g->tri_n = malloc((s->ntris ? s->ntris : 1) * 3 * sizeof(float));
    if (!g->tri_n)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for %zu triangle normals", s->ntris);
    /* In double: a sliver's cross product loses every digit in float. */
    for (size_t t = 0; t < s->ntris; t++) {
        const float *a = s->verts + 3 * s->tris[3 * t], *b = s->verts + 3 * s->tris[3 * t + 1],
                    *cc = s->verts + 3 * s->tris[3 * t + 2];
        double e1[3], e2[3], nn[3];
        for (int k = 0; k < 3; k++)
            e1[k] = (double)b[k] - a[k], e2[k] = (double)cc[k] - a[k];
        nn[0] = e1[1] * e2[2] - e1[2] * e2[1];
        nn[1] = e1[2] * e2[0] - e1[0] * e2[2];
        nn[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double l = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
        for (int k = 0; k < 3; k++)
            g->tri_n[3 * t + k] = l > 0.0 ? (float)(nn[k] / l) : (k == 2 ? 1.0f : 0.0f);
    }
    return PM_OK;
}

void pm_shade_geom_free(pm_shade_geom_t *g)
{
    free(g->tri_n);
    g->tri_n = NULL;
}
