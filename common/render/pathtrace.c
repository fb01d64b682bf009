/* pathtrace.c: the reference path tracer (pathtrace.h), the engine of trace-reference.
 *
 * Reads a scene and its Embree scene; writes an OpenEXR image of the mean radiance and, when
 * asked, a radiance buffer (formats/formats.h) with each pixel's variance, which is also what
 * a later run resumes from. Every reflection and pdf is render/transport.h's and every light
 * sample render/light.h's, the ones the photon tracers use, so the reference and the estimate it judges share one
 * physics. */
#include "render/pathtrace.h"

#include <float.h>
#include <inttypes.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/atomic.h"
#include "base/cpu.h"
#include "base/exr.h"
#include "base/progress.h"
#include "base/timer.h"
#include "base/version.h"
#include "formats/formats.h"
#include "math/rng.h"
#include "math/vec.h"

const char *const pm_pt_component_names[] = {"total", "direct", "indirect", "caustic", NULL};

/* Which component a contribution belongs to (pathtrace.h): nd non-specular vertices on the path
 * from the camera to the light, spec whether a mirror or glass lies between the last of them
 * and the light. */
static inline int component_of(unsigned nd, int spec)
{
    return nd >= 2 ? PM_PT_INDIRECT : nd == 1 && spec ? PM_PT_CAUSTIC : PM_PT_DIRECT;
}

/* Whether a contribution belongs to the component asked for. */
static inline int wanted(const pm_pathtracer_t *pt, unsigned nd, int spec)
{
    return pt->set.component == PM_PT_TOTAL || pt->set.component == component_of(nd, spec);
}

pm_result_t pm_pathtracer_init(pm_pathtracer_t *pt, const pm_scene_t *s, const pm_rt_t *rt,
                               const pm_pathtrace_settings_t *set)
{
    memset(pt, 0, sizeof *pt);
    pt->s = s, pt->rt = rt, pt->set = *set;
    if (pt->set.threads < 1)
        pt->set.threads = 1;
    pm_camera_setup(&s->camera, set->width, set->height, &pt->cam);
    size_t np = (size_t)set->width * set->height;
    pm_result_t r = pm_shade_geom_init(s, &pt->geom);
    if (r != PM_OK)
        return r;
    r = pm_lights_init(s, &pt->lights);
    if (r != PM_OK) {
        pm_shade_geom_free(&pt->geom);
        return r;
    }
    pt->mean = calloc(np * 3, sizeof(double));
    pt->m2 = calloc(np * 3, sizeof(double));
    pt->count = aligned_alloc(64, (size_t)pt->set.threads * sizeof *pt->count);
    if (!pt->mean || !pt->m2 || !pt->count) {
        pm_pathtracer_free(pt);
        return pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " image", set->width, set->height);
    }
    memset(pt->count, 0, (size_t)pt->set.threads * sizeof *pt->count);
    return PM_OK;
}

void pm_pathtracer_free(pm_pathtracer_t *pt)
{
    free(pt->mean);
    free(pt->m2);
    free(pt->count);
    pm_shade_geom_free(&pt->geom);
    pm_lights_free(&pt->lights);
    pt->mean = pt->m2 = NULL, pt->count = NULL;
}

void pm_pathtrace_sample(const pm_pathtracer_t *pt, struct RTCIntersectContext *ctx, uint32_t x, uint32_t y, uint32_t k,
                         pm_pathtrace_counts_t *cnt, double L[3])
{
    const pm_scene_t *s = pt->s;
    const pm_shade_geom_t *g = &pt->geom;
    const pm_lights_t *lights = &pt->lights;
    const float eps = pt->rt->epsilon;
    uint64_t pixel = (uint64_t)(y * pt->set.width + x) << 32;
    pm_rng_t rng;
    float jx = 0.5f, jy = 0.5f;
    if (pt->set.pixel == PM_PIXEL_BOX) {
        /* The pixel's scramble comes from a stream no sample uses (k < 4e9 < 2^32 - 1), so the
         * samples of a pixel stay stratified across passes and resumes. */
        pm_rng_init(&rng, pt->set.seed, pixel | UINT32_MAX);
        uint32_t sx = pm_rng_u32(&rng), sy = pm_rng_u32(&rng);
        pm_pixel_offset(k, sx, sy, &jx, &jy);
    }
    pm_rng_init(&rng, pt->set.seed, pixel | k);
    float o[3] = {pt->cam.eye[0], pt->cam.eye[1], pt->cam.eye[2]}, d[3], t = 0.0f;
    pm_camera_dir(&pt->cam, (float)x + jx, (float)y + jy, d);
    L[0] = L[1] = L[2] = 0.0;
    double beta[3] = {1.0, 1.0, 1.0}; /* path throughput: f cos / pdf products over survival */
    /* The product of eta^2 over the refractions so far: beta times it is the throughput
     * without the radiance scaling of refraction, which Russian roulette looks at, so that a
     * path into glass is not culled for a factor the way out gives back. */
    double eta2 = 1.0;
    float bsdf_pdf_prev = 0.0f;           /* solid-angle pdf of the BSDF sample that made this ray */
    float n_prev[3] = {0.0f, 0.0f, 1.0f}; /* the normal where that sample was taken (the sky's pdf) */
    int delta_prev = 0;                   /* the ray left a mirror or glass: no light sample could have found its end */
    unsigned nd = 0;                      /* non-specular vertices so far (the camera's side of the light path) */
    int spec = 0;                         /* a mirror or glass since the last of them */
    cnt->paths++;
    for (unsigned depth = 0;; depth++) {
        cnt->rays++;
        uint32_t tri = pm_rt_intersect1(pt->rt, ctx, o, d, 0.0f, INFINITY, &t, NULL);
        if (tri == PM_RAY_MISS) {
            /* Escaped: the lights at infinity. Seen by the camera or through mirrors and glass
             * they are taken whole; found by a BSDF sample, each shares with its own light
             * sample of the vertex before (power heuristic). */
            if (wanted(pt, nd, spec)) {
                int mis = depth > 0 && !delta_prev;
                double le_sum[3] = {0.0, 0.0, 0.0};
                int found = 0;
                for (size_t i = lights->ndelta; i < lights->ndirect; i++) {
                    if (!lights->direct[i].infinite)
                        continue;
                    found = 1;
                    float le[3],
                        w = mis ? pm_power_heuristic(bsdf_pdf_prev, pm_lights_pdf_li_escape(lights, i, n_prev, d))
                                : 1.0f;
                    pm_lights_le_escape_one(lights, i, d, le);
                    for (int q = 0; q < 3; q++)
                        le_sum[q] += (double)le[q] * w;
                }
                for (int q = 0; q < 3 && found; q++)
                    L[q] += beta[q] * le_sum[q];
            }
            break;
        }
        float p[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]}, wo[3] = {-d[0], -d[1], -d[2]};
        const float *ng = g->tri_n + 3 * (size_t)tri;
        float cos_front = pm_dot3(ng, wo), side = cos_front >= 0.0f ? 1.0f : -1.0f;
        float n[3] = {side * ng[0], side * ng[1], side * ng[2]};
        pm_material_t textured; /* the material with its textures at p (render/scene.h) */
        const pm_material_t *m = pm_scene_material_at(s, tri, p, &textured);
        int specular = pm_material_is_specular(m);

        /* Emission, front face only (both when two-sided). Seen by the camera, or through mirrors and glass, it
         * is taken whole; found by a BSDF sample it shares with the light sample of the vertex before (power
         * heuristic). */
        float le[3], cos_emit;
        if (pm_lights_le_hit(lights, tri, cos_front, le, &cos_emit) && cos_emit > 0.0f && wanted(pt, nd, spec)) {
            float w = 1.0f;
            if (depth > 0 && !delta_prev)
                w = pm_power_heuristic(bsdf_pdf_prev, pm_lights_pdf_li_hit(lights, t, cos_emit));
            for (int q = 0; q < 3; q++)
                L[q] += beta[q] * le[q] * w;
        }
        /* What lies beyond is of a component not asked for: not traced. Direct light ends at
         * the first non-specular vertex's light (nd 1, no mirror or glass after it); a caustic
         * at the first non-specular vertex's mirrors and glass (nd 1 and this hit specular). */
        if ((pt->set.component == PM_PT_DIRECT && nd >= 1) ||
            (pt->set.component == PM_PT_CAUSTIC && nd >= 1 && !specular))
            break;
        if (depth >= pt->set.max_bounces) {
            cnt->capped++;
            break;
        }
        if (specular) {
            /* A delta BSDF: no light sample (it could not find the light through a delta
             * lobe), no MIS; the sample carries the weight f cos / pdf. */
            float wi[3], w[3];
            int tr = pm_specular_sample(m, ng, wo, pm_rng_float(&rng), 1, wi, w);
            if (tr < 0)
                break; /* a black mirror */
            if (depth + 1 > cnt->longest)
                cnt->longest = depth + 1;
            for (int q = 0; q < 3; q++)
                beta[q] *= (double)w[q];
            if (tr == 1) {
                double e = cos_front < 0.0f ? 1.0 / m->ior : m->ior;
                eta2 *= e * e;
            }
            /* off the surface on the side the ray leaves by */
            float ofs = tr == 1 ? -eps : eps;
            for (int q = 0; q < 3; q++)
                o[q] = p[q] + ofs * n[q], d[q] = wi[q];
            spec = 1;
            delta_prev = 1;
        } else {
            float pd, ps;
            pm_bsdf_albedo(m, &pd, &ps);
            if (!(pd > 0.0f || pm_material_is_glossy(m)))
                break; /* black: reflects nothing */
            if (depth + 1 > cnt->longest)
                cnt->longest = depth + 1;
            float org[3] = {p[0] + eps * n[0], p[1] + eps * n[1], p[2] + eps * n[2]};
            /* sn: the shading normal (render/transport.h), n itself without vertex normals; n
             * still decides the side a ray leaves from, and no direction below it is taken. */
            float sn[3];
            /* A transmitting kind (rough glass) shades with the geometric normal, as glass does:
             * its side tells inside from outside. bn: the normal the BSDF reads (physics/bsdf.h),
             * the front one for a dielectric, sn for the reflective kinds. */
            int transmits = pm_bsdf_transmits(m);
            int shaded = transmits ? (memcpy(sn, n, sizeof sn), 0) : pm_scene_shading_normal(s, tri, p, n, sn);
            const float *bn = transmits ? ng : sn;

            /* Direct light, one sample of each light of the direct list (render/light.h): f Li
             * cos / pdf, a light that a BSDF sample can also find weighted against it (power
             * heuristic); a delta light alone. */
            for (size_t i = 0; i < lights->ndirect && wanted(pt, nd + 1, 0); i++) {
                pm_light_li_t li;
                if (!pm_lights_sample_li(lights, i, &rng, p, sn, &li) || (shaded && !(pm_dot3(n, li.wi) > 0.0f)))
                    continue; /* behind the shading or the geometric surface */
                cnt->shadow_rays++;
                if (pm_rt_occluded1(pt->rt, ctx, org, li.wi, 0.0f, pm_light_shadow_tmax(&li, eps)))
                    continue;
                float f[3];
                pm_brdf(m, bn, li.wi, wo, f);
                double gw = (double)li.cosx / li.pdf;
                if (!li.delta)
                    gw *= pm_power_heuristic(li.pdf, pm_bsdf_pdf(m, bn, li.wi, wo));
                for (int q = 0; q < 3; q++)
                    L[q] += beta[q] * (double)f[q] * li.Li[q] * gw;
            }

            /* Continue along a BSDF sample: the lobe, then two numbers for the direction. */
            float wi[3], u = pm_rng_float(&rng), u1 = pm_rng_float(&rng), u2 = pm_rng_float(&rng);
            if (m->kind != PM_MAT_STANDARD) {
                /* Conductor, rough glass, plastic: the BSDF's sampler gives the weight f cos / pdf
                 * and the lobe. A delta lobe (a smooth plastic's coat) is a specular bounce (no
                 * MIS for what it finds); so is a transmission as far as MIS goes, since no light
                 * sample looks below the surface. */
                pm_bsdf_sample_t bs;
                if (!pm_bsdf_sample_wi(m, bn, wo, u, u1, u2, PM_BSDF_RADIANCE, &bs))
                    break; /* absorbed, or the lobe's energy loss below or above the surface */
                int tr = (bs.lobe & PM_BSDF_TRANSMIT) != 0, delta = (bs.lobe & PM_BSDF_DELTA) != 0;
                if (shaded && !(pm_dot3(n, bs.wi) > 0.0f))
                    break; /* below the geometric surface: not taken (it would leak light through) */
                for (int q = 0; q < 3; q++)
                    beta[q] *= (double)bs.weight[q];
                if (tr)
                    eta2 *= (double)bs.eta * bs.eta;
                float ofs = tr ? -eps : eps;
                for (int q = 0; q < 3; q++)
                    o[q] = p[q] + ofs * n[q], d[q] = bs.wi[q];
                bsdf_pdf_prev = bs.pdf;
                memcpy(n_prev, sn, sizeof n_prev);
                if (delta)
                    spec = 1;
                else
                    nd++, spec = 0;
                delta_prev = delta || tr;
            } else {
                if (!pm_bsdf_sample(m, sn, wo, u, u1, u2, wi))
                    break; /* the Phong lobe's share below the surface: its energy loss */
                if (shaded && !(pm_dot3(n, wi) > 0.0f))
                    break; /* below the geometric surface: not taken (it would leak light through) */
                float pdf = pm_bsdf_pdf(m, sn, wi, wo), f[3];
                if (!(pdf > 0.0f))
                    break;
                pm_brdf(m, sn, wi, wo, f);
                float cosi = pm_dot3(sn, wi);
                for (int q = 0; q < 3; q++)
                    beta[q] *= (double)f[q] * cosi / pdf;
                bsdf_pdf_prev = pdf;
                memcpy(n_prev, sn, sizeof n_prev);
                memcpy(o, org, sizeof o);
                memcpy(d, wi, sizeof d);
                nd++;
                spec = 0;
                delta_prev = 0;
            }
        }
        if (depth + 1 >= pt->set.rr_start) {
            double qs = fmax(beta[0], fmax(beta[1], beta[2])) * eta2;
            if (qs < 1.0) {
                if (!(pm_rng_double(&rng) < qs))
                    break;
                for (int q = 0; q < 3; q++)
                    beta[q] /= qs;
            }
        }
    }
    if (!(isfinite(L[0]) && isfinite(L[1]) && isfinite(L[2]))) {
        cnt->nonfinite++; /* counted and reported; never written */
        L[0] = L[1] = L[2] = 0.0;
    }
}

pm_result_t pm_pathtrace_pass(pm_pathtracer_t *pt, uint32_t k1)
{
    uint32_t k0 = (uint32_t)pt->n, w = pt->set.width, h = pt->set.height;
    double nb = (double)(k1 - k0), na = (double)pt->n, nn = na + nb;
    pm_error_slot_t err;
    pm_error_slot_init(&err);
#pragma omp parallel num_threads(pt->set.threads)
    {
        pm_cpu_set_ftz_daz();
        pm_pathtrace_counts_t *my = &pt->count[omp_get_thread_num()];
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
#pragma omp for schedule(dynamic, 1)
        for (uint32_t y = 0; y < h; y++) {
            for (uint32_t x = 0; x < w; x++) {
                double mean[3] = {0, 0, 0}, m2[3] = {0, 0, 0}, L[3];
                for (uint32_t k = k0; k < k1; k++) {
                    pm_pathtrace_sample(pt, &ctx, x, y, k, my, L);
                    double j = (double)(k - k0 + 1);
                    for (int q = 0; q < 3; q++) {
                        double dl = L[q] - mean[q];
                        mean[q] += dl / j;
                        m2[q] += dl * (L[q] - mean[q]);
                    }
                }
                size_t i = 3 * ((size_t)y * w + x);
                for (int q = 0; q < 3; q++) {
                    double dl = mean[q] - pt->mean[i + q];
                    pt->mean[i + q] += dl * (nb / nn);
                    pt->m2[i + q] += m2[q] + dl * dl * (na * nb / nn);
                }
            }
            /* The message is this worker's: it reaches the caller through the slot. */
            pm_result_t r =
                pm_rt_thread_error(pt->rt, "tracing row %" PRIu32 " of samples %" PRIu32 "..%" PRIu32, y, k0, k1 - 1);
            if (r != PM_OK)
                pm_error_slot_record(&err, y, r);
        }
    }
    pm_result_t r = pm_error_slot_raise(&err);
    if (r == PM_OK)
        pt->n = k1;
    return r;
}

void pm_pathtrace_counts(const pm_pathtracer_t *pt, pm_pathtrace_counts_t *sum)
{
    memset(sum, 0, sizeof *sum);
    for (int i = 0; i < pt->set.threads && pt->count; i++) {
        const pm_pathtrace_counts_t *c = &pt->count[i];
        sum->paths += c->paths, sum->rays += c->rays, sum->shadow_rays += c->shadow_rays;
        sum->capped += c->capped, sum->nonfinite += c->nonfinite;
        if (c->longest > sum->longest)
            sum->longest = c->longest;
    }
}

void pm_pathtrace_image_error(const pm_pathtracer_t *pt, double *rmse, double *mean_out, double *rel)
{
    size_t np = (size_t)pt->set.width * pt->set.height * 3;
    double v = 0.0, m = 0.0;
    for (size_t i = 0; i < np; i++) {
        m += pt->mean[i];
        if (pt->n > 1)
            v += pt->m2[i] / ((double)pt->n * (double)(pt->n - 1));
    }
    *rmse = np ? sqrt(v / (double)np) : 0.0;
    *mean_out = np ? m / (double)np : 0.0;
    *rel = *mean_out > 0.0 ? *rmse / *mean_out : 0.0;
}

/* The radiance buffer's header: the image keys, then what a resume must match. */
static pm_result_t header_common(pm_header_t *h, const pm_pathtracer_t *pt, const pm_pathtrace_output_t *out)
{
    const pm_pathtrace_settings_t *c = &pt->set;
    pm_result_t r = pm_image_header_begin(h, out->argc, out->argv, pt->s, c->width, c->height);
    if (r == PM_OK)
        r = pm_header_set(h, "component", "%s", pm_pt_component_names[c->component]);
    if (r == PM_OK)
        r = pm_header_set(h, "estimator", "path-tracer");
    if (r == PM_OK)
        r = pm_header_set(h, "samples", "%" PRIu64, pt->n);
    if (r == PM_OK)
        r = pm_header_set(h, "seed", "%" PRIu64, c->seed);
    if (r == PM_OK)
        r = pm_header_set(h, "pixel", "%s", pm_pixel_names[c->pixel]);
    if (r == PM_OK)
        r = pm_header_set(h, "max_bounces", "%u", c->max_bounces);
    if (r == PM_OK)
        r = pm_header_set(h, "rr_start", "%u", c->rr_start);
    return r;
}

pm_result_t pm_pathtrace_write(const pm_pathtracer_t *pt, const pm_pathtrace_output_t *out)
{
    const pm_pathtrace_settings_t *c = &pt->set;
    size_t np = (size_t)c->width * c->height;
    float *rgb = malloc(np * 3 * sizeof(float));
    if (!rgb)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " image", c->width, c->height);
    pm_atomic_set_t set; /* the EXR and the radiance buffer of a pass appear together, or neither */
    pm_atomic_set_begin(&set);
    pm_result_t r = PM_OK;
    for (size_t i = 0; i < 3 * np && r == PM_OK; i++) {
        if (!(pt->mean[i] <= FLT_MAX))
            r = pm_error_set(PM_ERR_INPUT, "pixel (%zu, %zu) of '%s': radiance %g W/(m^2 sr) does not fit in a float",
                             i / 3 % c->width, i / 3 / c->width, out->exr, pt->mean[i]);
        rgb[i] = (float)pt->mean[i];
    }
    char id[200], samples[32], seed[32], rmse_s[32];
    double rmse, mean, rel;
    pm_pathtrace_image_error(pt, &rmse, &mean, &rel);
    pm_scene_id(pt->s, id, sizeof id);
    snprintf(samples, sizeof samples, "%" PRIu64, pt->n);
    snprintf(seed, sizeof seed, "%" PRIu64, c->seed);
    snprintf(rmse_s, sizeof rmse_s, "%.6g", rmse);
    const pm_exr_attr_t attrs[] = {
        {"SOFTWARE", "pmtk " PM_VERSION_STRING},
        {"SCENE", id},
        {"COMMAND.0", out->command},
        {"components", pm_pt_component_names[c->component]},
        {"estimator", "path-tracer"},
        {"samples", samples},
        {"seed", seed},
        {"pixel", pm_pixel_names[c->pixel]},
        {"stderr_rms", rmse_s},
    };
    /* The layers a denoiser reads (--aov): the variance of each pixel's mean, the surface's */
    float *var = NULL;
    if (r == PM_OK && (out->aov & PM_EXR_AOV_VARIANCE)) {
        if (!(var = malloc(np * 3 * sizeof *var)))
            r = pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " variance layer", c->width,
                             c->height);
        for (size_t i = 0; r == PM_OK && i < 3 * np; i++) {
            double v = pt->n > 1 ? pt->m2[i] / ((double)pt->n * (double)(pt->n - 1)) : 0.0;
            if (!(v <= FLT_MAX))
                r = pm_error_set(PM_ERR_INPUT, "pixel (%zu, %zu) of '%s': variance %g does not fit in a float",
                                 i / 3 % c->width, i / 3 / c->width, out->exr, v);
            else
                var[i] = (float)v;
        }
    }
    pm_exr_channel_t ch[PM_EXR_MAX_CHANNELS] = {{"R", rgb, 3, 0}, {"G", rgb + 1, 3, 0}, {"B", rgb + 2, 3, 0}};
    size_t nch = 3 + pm_exr_aov_channels(out->aov, out->surf, var, ch + 3);
    if (r == PM_OK)
        r = pm_exr_write_channels(out->exr, c->width, c->height, ch, nch, PM_EXR_FLOAT, PM_EXR_ZIP, attrs,
                                  sizeof attrs / sizeof attrs[0]);
    free(var);
    free(rgb);
    if (r != PM_OK || !out->radiance)
        return pm_atomic_set_end(&set, r);

    pm_table_t t = {0};
    r = pm_table_alloc(&t, &pm_radiance_schema, (1u << PM_RADIANCE_RGB) | (1u << PM_RADIANCE_VARIANCE), np);
    if (r == PM_OK)
        r = header_common(&t.hdr, pt, out);
    if (r == PM_OK) {
        double *m = t.col[PM_RADIANCE_RGB], *v = t.col[PM_RADIANCE_VARIANCE];
        memcpy(m, pt->mean, np * 3 * sizeof(double));
        for (size_t i = 0; i < 3 * np; i++)
            v[i] = pt->n > 1 ? pt->m2[i] / ((double)pt->n * (double)(pt->n - 1)) : 0.0;
        r = pm_table_write(&t, out->radiance);
    }
    pm_table_free(&t);
    return pm_atomic_set_end(&set, r);
}

pm_result_t pm_pathtrace_resume(pm_pathtracer_t *pt, const char *path)
{
    const pm_pathtrace_settings_t *c = &pt->set;
    pm_table_t t;
    pm_result_t r =
        pm_table_read(path, &pm_radiance_schema, (1u << PM_RADIANCE_RGB) | (1u << PM_RADIANCE_VARIANCE), &t);
    if (r != PM_OK)
        return r;
    uint32_t w, h;
    uint64_t n = 0, seed = 0;
    char id[200];
    pm_scene_id(pt->s, id, sizeof id);
    const char *est = pm_header_get(&t.hdr, "estimator"), *scene = pm_header_get(&t.hdr, "SCENE"),
               *pix = pm_header_get(&t.hdr, "pixel"), *comp = pm_header_get(&t.hdr, "component");
    const char *want_pix = pm_pixel_names[c->pixel], *want_comp = pm_pt_component_names[c->component];
    if ((r = pm_header_get_image_size(&t.hdr, path, &w, &h)) != PM_OK ||
        (r = pm_header_get_u64(&t.hdr, path, "samples", &n)) != PM_OK ||
        (r = pm_header_get_u64(&t.hdr, path, "seed", &seed)) != PM_OK)
        goto done;
    if (!est || strcmp(est, "path-tracer"))
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s' was not written by trace-reference (estimator '%s')", path,
                         est ? est : "(missing)");
    else if (!scene || !pm_scene_id_matches(pt->s, scene))
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s' is of scene '%s', not '%s'", path, scene ? scene : "(missing)",
                         id);
    else if (w != c->width || h != c->height)
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s' is %" PRIu32 "x%" PRIu32 ", this render %" PRIu32 "x%" PRIu32,
                         path, w, h, c->width, c->height);
    else if (seed != c->seed)
        r = pm_error_set(PM_ERR_INPUT,
                         "--resume '%s' has seed %" PRIu64 ", this render %" PRIu64
                         " (its samples would repeat or differ)",
                         path, seed, c->seed);
    else if (!pix || strcmp(pix, want_pix))
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s' has pixel '%s', this render '%s'", path, pix ? pix : "(missing)",
                         want_pix);
    else if (!comp || strcmp(comp, want_comp))
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s' is component '%s', this render '%s'", path,
                         comp ? comp : "(missing)", want_comp);
    else if (n == 0 || n >= UINT32_MAX)
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s': samples=%" PRIu64 " is not in [1, 2^32)", path, n);
    if (r != PM_OK)
        goto done;
    size_t np = (size_t)w * h * 3;
    const double *m = t.col[PM_RADIANCE_RGB], *v = t.col[PM_RADIANCE_VARIANCE];
    for (size_t i = 0; i < np; i++) {
        pt->mean[i] = m[i];
        pt->m2[i] = v[i] * (double)n * (double)(n - 1);
    }
    pt->n = n;
done:
    pm_table_free(&t);
    return r;
}

pm_result_t pm_pathtrace_render(pm_pathtracer_t *pt, const pm_pathtrace_plan_t *plan, const pm_pathtrace_output_t *out,
                                pm_pathtrace_run_t *run)
{
    memset(run, 0, sizeof *run);
    run->resumed = pt->n;
    pm_result_t r = PM_OK;
    pm_progress_t prog;
    uint64_t todo = plan->spp > pt->n ? plan->spp - pt->n : 0;
    pm_progress_begin(&prog, "samples", todo, plan->progress);
    double t0 = pm_time_wall();
    while (r == PM_OK && pt->n < plan->spp) {
        if (plan->time_s > 0.0 && run->passes > 0 && pm_time_wall() - t0 >= plan->time_s) {
            run->timed_out = 1;
            break;
        }
        uint64_t k0 = pt->n, k1 = k0 + plan->pass < plan->spp ? k0 + plan->pass : plan->spp;
        r = pm_pathtrace_pass(pt, (uint32_t)k1);
        if (r != PM_OK)
            break;
        run->passes++;
        pm_progress_add(&prog, k1 - k0);
        double tw = pm_time_wall();
        r = pm_pathtrace_write(pt, out);
        run->write_s += pm_time_wall() - tw;
    }
    run->trace_s = pm_time_wall() - t0 - run->write_s;
    pm_progress_end(&prog);
    if (r == PM_OK && run->passes == 0)
        r = pm_pathtrace_write(pt, out); /* already at spp: the outputs say so */
    return r;
}
