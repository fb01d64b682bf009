/* trace-reference: ground truth for the photon pipeline. An unbiased path tracer over the same
 * scene model as trace-photons and trace-gather-points (common/render/shade.h: camera, BRDF, front-face
 * emitters; point lights in W/sr, Ke in W/(m^2 sr)), so that measure-error can say how wrong a
 * photon-mapped image is.
 *
 * Estimator: at every vertex, next-event estimation toward each point light (delta: light
 * sampling only) and toward one point on the area lights (uniform over their total area, as
 * trace-gather-points samples them), combined with BRDF sampling by the power heuristic; the
 * BRDF is sampled as a mixture of its cosine and Phong lobes. Paths end by Russian roulette
 * with survival min(1, max throughput), which keeps them unbiased and their weights bounded
 * by 1 at any albedo; --max-bounces is a safety net whose hits are counted in --stats.
 *
 * Progressive: passes of --pass samples per pixel until --spp in all or --time seconds;
 * after every pass the image (-o, OpenEXR) and, with --radiance, the f64 buffer with the
 * per-pixel variance of the estimate are rewritten atomically, so a long run can be stopped
 * at any time and continued with --resume. Sample k of pixel p draws from the Philox stream
 * (seed, p << 32 | k) whatever the thread, pass or resume, and pixels are summed sample by
 * sample in order: the same settings give the same bits for any --threads. */
#include <float.h>
#include <inttypes.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/cpu.h"
#include "base/exr.h"
#include "math/rng.h"
#include "render/rt.h"
#include "math/sampling.h"
#include "render/shade.h"
#include "base/stage.h"
#include "base/version.h"
#include "formats/formats.h"

enum { PIXEL_CENTER = 0, PIXEL_BOX = 1 };
static const char *const pixel_names[] = {"center", "box", NULL};
/* Which light: a contribution that reflected b times on its way to the camera (emission seen
 * directly b = 0, direct light b = 1) is direct for b <= 1 and indirect beyond, as
 * trace-gather-points' direct buffer and simd-gather's indirect one split it. */
enum { COMP_TOTAL = 0, COMP_DIRECT = 1, COMP_INDIRECT = 2 };
static const char *const component_names[] = {"total", "direct", "indirect", NULL};

typedef struct {
    int64_t spp;          /* samples per pixel in all, resumed ones included */
    int64_t pass;         /* samples per pixel per pass */
    double time_s;        /* stop after this many seconds (at a pass boundary); 0: no limit */
    int64_t max_bounces;  /* safety net: a path is cut after this many bounces */
    int64_t rr_start;     /* bounces before Russian roulette starts */
    int64_t width, height;
    int pixel, component;
    const char *radiance; /* --radiance FILE: f64 mean and variance per pixel */
    const char *resume;   /* --resume FILE: a --radiance file to continue */
} ref_options_t;

typedef struct {
    const pm_scene_t *s;
    const pm_rt_t *rt;
    pm_shade_geom_t geom;
    pm_camera_rays_t cam;
    uint32_t w, h;
    uint64_t seed;
    unsigned max_bounces, rr_start;
    int pixel, component;
    float eps;
} ref_ctx_t;

/* Whether a contribution that reflected b times belongs to the component asked for. */
static inline int wanted(const ref_ctx_t *c, unsigned b)
{
    return c->component == COMP_TOTAL || (c->component == COMP_DIRECT) == (b <= 1);
}

/* Per-thread counters, each on its own cache line (written on every ray). */
typedef struct {
    _Alignas(64) uint64_t paths, rays, shadow_rays, capped, nonfinite, longest;
} ref_counts_t;

static inline float dot3(const float *a, const float *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static inline float max3(const float *v) { return fmaxf(v[0], fmaxf(v[1], v[2])); }

/* Probability of choosing the diffuse lobe when sampling the BRDF: the lobes' shares of the
 * albedo (as trace-photons chooses them); 1 for Lambertian materials. */
static inline float diffuse_share(const pm_material_t *m)
{
    float pd = max3(m->kd), ps = max3(m->ks);
    return pd + ps > 0.0f ? pd / (pd + ps) : 1.0f;
}

/* Solid-angle pdf of BRDF sampling producing wi, 1/sr. */
static float brdf_pdf(const pm_material_t *m, const float n[3], const float wi[3], const float wo[3])
{
    float cosi = dot3(n, wi);
    if (cosi <= 0.0f)
        return 0.0f;
    float sd = diffuse_share(m), p = sd * cosi * (1.0f / PM_PI);
    if (sd < 1.0f) {
        float c = 2.0f * dot3(n, wo), r[3] = {c * n[0] - wo[0], c * n[1] - wo[1], c * n[2] - wo[2]};
        float ca = dot3(r, wi);
        if (ca > 0.0f)
            p += (1.0f - sd) * (m->ns + 1.0f) / (2.0f * PM_PI) * powf(ca, m->ns);
    }
    return p;
}

/* Samples wi from the BRDF mixture; 0 when the sample falls below the surface. */
static int brdf_sample(const pm_material_t *m, const float n[3], const float wo[3], pm_rng_t *rng, float wi[3])
{
    float u = pm_rng_float(rng), u1 = pm_rng_float(rng), u2 = pm_rng_float(rng);
    pm_vec3_t t, b, d;
    if (u < diffuse_share(m)) {
        pm_vec3_t nn = pm_v3_load(n);
        pm_onb(nn, &t, &b);
        d = pm_onb_to_world(pm_sample_cosine_hemisphere(u1, u2), t, b, nn);
    } else {
        /* cos^ns about the mirror direction of wo: pdf (ns + 1) / (2 pi) cos^ns. */
        float c = 2.0f * dot3(n, wo);
        pm_vec3_t r = pm_v3_normalize(pm_v3(c * n[0] - wo[0], c * n[1] - wo[1], c * n[2] - wo[2]));
        float ca = powf(u1, 1.0f / (m->ns + 1.0f)), sa = sqrtf(fmaxf(0.0f, 1.0f - ca * ca)), phi = 2.0f * PM_PI * u2;
        pm_onb(r, &t, &b);
        d = pm_v3_normalize(pm_onb_to_world(pm_v3(sa * cosf(phi), sa * sinf(phi), ca), t, b, r));
    }
    pm_v3_store(wi, d);
    return dot3(n, wi) > 0.0f;
}

static inline int occluded(const ref_ctx_t *c, struct RTCIntersectContext *ctx, const float o[3], const float d[3],
                           float tfar)
{
    struct RTCRay ray = {.org_x = o[0], .org_y = o[1], .org_z = o[2], .tnear = 0.0f,
                         .dir_x = d[0], .dir_y = d[1], .dir_z = d[2], .time = 0.0f,
                         .tfar = tfar, .mask = 0xffffffffu, .id = 0, .flags = 0};
    rtcOccluded1(c->rt->scene, ctx, &ray);
    return ray.tfar < 0.0f;
}

/* Traces ray (o, d); returns the triangle hit (and its distance in *t) or PM_RAY_MISS. */
static inline uint32_t intersect(const ref_ctx_t *c, struct RTCIntersectContext *ctx, const float o[3],
                                 const float d[3], float *t)
{
    struct RTCRayHit rh;
    rh.ray.org_x = o[0], rh.ray.org_y = o[1], rh.ray.org_z = o[2], rh.ray.tnear = 0.0f;
    rh.ray.dir_x = d[0], rh.ray.dir_y = d[1], rh.ray.dir_z = d[2], rh.ray.time = 0.0f;
    rh.ray.tfar = INFINITY, rh.ray.mask = 0xffffffffu, rh.ray.id = 0, rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(c->rt->scene, ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID)
        return UINT32_MAX;
    *t = rh.ray.tfar;
    return rh.hit.primID;
}

/* One path through pixel (x, y), sample k: its radiance estimate, W/(m^2 sr), in L. */
static void trace_path(const ref_ctx_t *c, struct RTCIntersectContext *ctx, uint32_t x, uint32_t y, uint32_t k,
                       ref_counts_t *cnt, double L[3])
{
    const pm_scene_t *s = c->s;
    pm_rng_t rng;
    pm_rng_init(&rng, c->seed, ((uint64_t)(y * c->w + x) << 32) | k);
    float jx = 0.5f, jy = 0.5f;
    if (c->pixel == PIXEL_BOX)
        jx = pm_rng_float(&rng), jy = pm_rng_float(&rng);
    float o[3] = {c->cam.eye[0], c->cam.eye[1], c->cam.eye[2]}, d[3], t = 0.0f;
    pm_camera_dir(&c->cam, (float)x + jx, (float)y + jy, d);
    L[0] = L[1] = L[2] = 0.0;
    double beta[3] = {1.0, 1.0, 1.0}; /* path throughput: f cos / pdf products over survival */
    float bsdf_pdf_prev = 0.0f;       /* solid-angle pdf of the BRDF sample that made this ray */
    cnt->paths++;
    for (unsigned depth = 0;; depth++) {
        cnt->rays++;
        uint32_t tri = intersect(c, ctx, o, d, &t);
        if (tri == UINT32_MAX)
            break; /* no sky: escaped light is lost */
        float p[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]}, wo[3] = {-d[0], -d[1], -d[2]};
        const float *ng = c->geom.tri_n + 3 * (size_t)tri;
        float cos_front = dot3(ng, wo), side = cos_front >= 0.0f ? 1.0f : -1.0f;
        float n[3] = {side * ng[0], side * ng[1], side * ng[2]};
        const pm_material_t *m = &s->materials[s->tri_material[tri]];

        /* Emission, front face only. Seen by the camera it is taken whole; found by a BRDF
         * sample it shares with the light sample of the vertex before (power heuristic). */
        if (cos_front > 0.0f && pm_material_is_emissive(m) && wanted(c, depth)) {
            float w = 1.0f;
            if (depth > 0) {
                float pl = t * t / (cos_front * (float)c->geom.area);
                w = pm_power_heuristic(bsdf_pdf_prev, pl);
            }
            for (int q = 0; q < 3; q++)
                L[q] += beta[q] * m->ke[q] * w;
        }
        if (c->component == COMP_DIRECT && depth >= 1)
            break; /* what lies beyond is indirect: not traced */
        if (depth >= c->max_bounces) {
            cnt->capped++;
            break;
        }
        if (!(max3(m->kd) > 0.0f || pm_material_is_glossy(m)))
            break; /* black: reflects nothing */
        if (depth + 1 > cnt->longest)
            cnt->longest = depth + 1;
        float org[3] = {p[0] + c->eps * n[0], p[1] + c->eps * n[1], p[2] + c->eps * n[2]};

        /* Point lights: I cos / r^2, each one every vertex. */
        pm_light_sample_t ls;
        for (size_t l = 0; l < s->nlights && wanted(c, depth + 1); l++) {
            const pm_point_light_t *pl = &s->lights[l];
            if (!pm_point_light_toward(pl, p, n, &ls))
                continue;
            cnt->shadow_rays++;
            if (occluded(c, ctx, org, ls.wi, ls.r - c->eps))
                continue;
            float f[3];
            pm_brdf(m, n, ls.wi, wo, f);
            for (int q = 0; q < 3; q++)
                L[q] += beta[q] * (double)f[q] * pl->intensity[q] * ls.cosx / ls.r2;
        }
        /* One point on the area lights, pdf 1/A per m^2, weighted against BRDF sampling. */
        if (c->geom.nemissive && pm_area_light_sample(s, &c->geom, &rng, p, n, &ls) && wanted(c, depth + 1)) {
            cnt->shadow_rays++;
            if (!occluded(c, ctx, org, ls.wi, ls.r * (1.0f - 1e-4f) - 2.0f * c->eps)) {
                const pm_material_t *lm = &s->materials[s->tri_material[ls.tri]];
                float pl = ls.r2 / (ls.cosy * (float)c->geom.area), pb = brdf_pdf(m, n, ls.wi, wo), f[3];
                pm_brdf(m, n, ls.wi, wo, f);
                double g = (double)ls.cosx / pl * pm_power_heuristic(pl, pb);
                for (int q = 0; q < 3; q++)
                    L[q] += beta[q] * (double)f[q] * lm->ke[q] * g;
            }
        }

        /* Continue along a BRDF sample. */
        float wi[3];
        if (!brdf_sample(m, n, wo, &rng, wi))
            break; /* the Phong lobe's share below the surface: its energy loss */
        float pdf = brdf_pdf(m, n, wi, wo), f[3];
        if (!(pdf > 0.0f))
            break;
        pm_brdf(m, n, wi, wo, f);
        float cosi = dot3(n, wi);
        for (int q = 0; q < 3; q++)
            beta[q] *= (double)f[q] * cosi / pdf;
        if (depth + 1 >= c->rr_start) {
            double qs = fmax(beta[0], fmax(beta[1], beta[2]));
            if (qs < 1.0) {
                if (!(pm_rng_double(&rng) < qs))
                    break;
                for (int q = 0; q < 3; q++)
                    beta[q] /= qs;
            }
        }
        bsdf_pdf_prev = pdf;
        memcpy(o, org, sizeof o);
        memcpy(d, wi, sizeof d);
    }
    if (!(isfinite(L[0]) && isfinite(L[1]) && isfinite(L[2]))) {
        cnt->nonfinite++; /* counted and reported; never written */
        L[0] = L[1] = L[2] = 0.0;
    }
}

/* Running per-pixel statistics: n samples, their mean and sum of squared deviations (M2),
 * merged pass by pass (Chan et al.), so neither cancels in long runs. */
typedef struct {
    double *mean, *m2; /* 3 per pixel */
    uint64_t n;
} ref_accum_t;

/* Samples [k0, k1) of every pixel of rows [y0, y1) merged into a. */
static void run_pass(const ref_ctx_t *c, ref_accum_t *a, uint32_t k0, uint32_t k1, int nthreads, ref_counts_t *cnt)
{
    double nb = (double)(k1 - k0), na = (double)a->n, nn = na + nb;
#pragma omp parallel num_threads(nthreads)
    {
        pm_cpu_set_ftz_daz();
        ref_counts_t *my = &cnt[omp_get_thread_num()];
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
#pragma omp for schedule(dynamic, 1)
        for (uint32_t y = 0; y < c->h; y++) {
            for (uint32_t x = 0; x < c->w; x++) {
                double mean[3] = {0, 0, 0}, m2[3] = {0, 0, 0}, L[3];
                for (uint32_t k = k0; k < k1; k++) {
                    trace_path(c, &ctx, x, y, k, my, L);
                    double j = (double)(k - k0 + 1);
                    for (int q = 0; q < 3; q++) {
                        double dl = L[q] - mean[q];
                        mean[q] += dl / j;
                        m2[q] += dl * (L[q] - mean[q]);
                    }
                }
                size_t i = 3 * ((size_t)y * c->w + x);
                for (int q = 0; q < 3; q++) {
                    double dl = mean[q] - a->mean[i + q];
                    a->mean[i + q] += dl * (nb / nn);
                    a->m2[i + q] += m2[q] + dl * dl * (na * nb / nn);
                }
            }
        }
    }
    a->n += k1 - k0;
}

/* How wrong the image is by its own spread: RMS standard error over pixels and channels,
 * and that over the mean radiance. */
static void image_error(const ref_ctx_t *c, const ref_accum_t *a, double *rmse, double *mean_out, double *rel)
{
    size_t np = (size_t)c->w * c->h * 3;
    double v = 0.0, m = 0.0;
    for (size_t i = 0; i < np; i++) {
        m += a->mean[i];
        if (a->n > 1)
            v += a->m2[i] / ((double)a->n * (double)(a->n - 1));
    }
    *rmse = np ? sqrt(v / (double)np) : 0.0;
    *mean_out = np ? m / (double)np : 0.0;
    *rel = *mean_out > 0.0 ? *rmse / *mean_out : 0.0;
}

static pm_result_t header_common(pm_header_t *h, const pm_stage_t *st, const ref_ctx_t *c, uint64_t n)
{
    pm_result_t r = pm_image_header_begin(h, st->argc, st->argv, c->s, c->w, c->h);
    if (r == PM_OK)
        r = pm_header_set(h, "component", "%s", component_names[c->component]);
    if (r == PM_OK)
        r = pm_header_set(h, "estimator", "path-tracer");
    if (r == PM_OK)
        r = pm_header_set(h, "samples", "%" PRIu64, n);
    if (r == PM_OK)
        r = pm_header_set(h, "seed", "%" PRIu64, c->seed);
    if (r == PM_OK)
        r = pm_header_set(h, "pixel", "%s", pixel_names[c->pixel]);
    if (r == PM_OK)
        r = pm_header_set(h, "max_bounces", "%u", c->max_bounces);
    if (r == PM_OK)
        r = pm_header_set(h, "rr_start", "%u", c->rr_start);
    return r;
}

/* The image and, with --radiance, the buffer of means and variances, both atomically. */
static pm_result_t write_outputs(const pm_stage_t *st, const ref_options_t *o, const ref_ctx_t *c,
                                 const ref_accum_t *a)
{
    size_t np = (size_t)c->w * c->h;
    float *rgb = malloc(np * 3 * sizeof(float));
    if (!rgb)
        return pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " image", c->w, c->h);
    pm_result_t r = PM_OK;
    for (size_t i = 0; i < 3 * np && r == PM_OK; i++) {
        if (!(a->mean[i] <= FLT_MAX))
            r = pm_error_set(PM_ERR_INPUT, "pixel (%zu, %zu) of '%s': radiance %g W/(m^2 sr) does not fit in a float",
                             i / 3 % c->w, i / 3 / c->w, st->output, a->mean[i]);
        rgb[i] = (float)a->mean[i];
    }
    char id[200], samples[32], seed[32], rmse_s[32], cmd[4096];
    double rmse, mean, rel;
    image_error(c, a, &rmse, &mean, &rel);
    pm_scene_id(c->s, id, sizeof id);
    snprintf(samples, sizeof samples, "%" PRIu64, a->n);
    snprintf(seed, sizeof seed, "%" PRIu64, c->seed);
    snprintf(rmse_s, sizeof rmse_s, "%.6g", rmse);
    pm_stage_command_line(st, cmd, sizeof cmd);
    const pm_exr_attr_t attrs[] = {
        {"SOFTWARE", "pmtk " PM_VERSION_STRING}, {"SCENE", id}, {"COMMAND.0", cmd}, {"components", component_names[c->component]},
        {"estimator", "path-tracer"}, {"samples", samples}, {"seed", seed}, {"pixel", pixel_names[c->pixel]},
        {"stderr_rms", rmse_s},
    };
    if (r == PM_OK)
        r = pm_exr_write_rgb(st->output, c->w, c->h, rgb, PM_EXR_FLOAT, PM_EXR_ZIP, attrs,
                             sizeof attrs / sizeof attrs[0]);
    free(rgb);
    if (r != PM_OK || !o->radiance)
        return r;

    pm_table_t t = {0};
    r = pm_table_alloc(&t, &pm_radiance_schema, (1u << PM_RADIANCE_RGB) | (1u << PM_RADIANCE_VARIANCE), np);
    if (r == PM_OK)
        r = header_common(&t.hdr, st, c, a->n);
    if (r == PM_OK) {
        double *m = t.col[PM_RADIANCE_RGB], *v = t.col[PM_RADIANCE_VARIANCE];
        memcpy(m, a->mean, np * 3 * sizeof(double));
        for (size_t i = 0; i < 3 * np; i++)
            v[i] = a->n > 1 ? a->m2[i] / ((double)a->n * (double)(a->n - 1)) : 0.0;
        r = pm_table_write(&t, o->radiance);
    }
    pm_table_free(&t);
    return r;
}

/* Takes over the samples of an earlier --radiance file of this very render. */
static pm_result_t resume(const ref_ctx_t *c, const char *path, ref_accum_t *a)
{
    pm_table_t t;
    pm_result_t r = pm_table_read(path, &pm_radiance_schema, (1u << PM_RADIANCE_RGB) | (1u << PM_RADIANCE_VARIANCE), &t);
    if (r != PM_OK)
        return r;
    uint32_t w, h;
    uint64_t n = 0, seed = 0;
    char id[200];
    pm_scene_id(c->s, id, sizeof id);
    const char *est = pm_header_get(&t.hdr, "estimator"), *scene = pm_header_get(&t.hdr, "SCENE"),
               *pix = pm_header_get(&t.hdr, "pixel"), *comp = pm_header_get(&t.hdr, "component");
    if ((r = pm_header_get_image_size(&t.hdr, path, &w, &h)) != PM_OK ||
        (r = pm_header_get_u64(&t.hdr, path, "samples", &n)) != PM_OK ||
        (r = pm_header_get_u64(&t.hdr, path, "seed", &seed)) != PM_OK)
        goto done;
    if (!est || strcmp(est, "path-tracer"))
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s' was not written by trace-reference (estimator '%s')", path,
                         est ? est : "(missing)");
    else if (!scene || strcmp(scene, id))
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s' is of scene '%s', not '%s'", path, scene ? scene : "(missing)", id);
    else if (w != c->w || h != c->h)
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s' is %" PRIu32 "x%" PRIu32 ", this render %" PRIu32 "x%" PRIu32,
                         path, w, h, c->w, c->h);
    else if (seed != c->seed)
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s' has seed %" PRIu64 ", this render %" PRIu64
                         " (its samples would repeat or differ)", path, seed, c->seed);
    else if (!pix || strcmp(pix, pixel_names[c->pixel]))
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s' has pixel '%s', this render '%s'", path, pix ? pix : "(missing)",
                         pixel_names[c->pixel]);
    else if (!comp || strcmp(comp, component_names[c->component]))
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s' is component '%s', this render '%s'", path,
                         comp ? comp : "(missing)", component_names[c->component]);
    else if (n == 0 || n >= UINT32_MAX)
        r = pm_error_set(PM_ERR_INPUT, "--resume '%s': samples=%" PRIu64 " is not in [1, 2^32)", path, n);
    if (r != PM_OK)
        goto done;
    size_t np = (size_t)w * h * 3;
    const double *m = t.col[PM_RADIANCE_RGB], *v = t.col[PM_RADIANCE_VARIANCE];
    for (size_t i = 0; i < np; i++) {
        a->mean[i] = m[i];
        a->m2[i] = v[i] * (double)n * (double)(n - 1);
    }
    a->n = n;
done:
    pm_table_free(&t);
    return r;
}

static pm_result_t run(pm_stage_t *st, const ref_options_t *o, const pm_scene_t *s, const pm_rt_t *rt)
{
    ref_ctx_t c = {.s = s, .rt = rt, .seed = (uint64_t)st->seed, .pixel = o->pixel, .component = o->component,
                   .eps = rt->epsilon,
                   .max_bounces = (unsigned)o->max_bounces, .rr_start = (unsigned)o->rr_start};
    c.w = o->width ? (uint32_t)o->width : s->camera.width;
    c.h = o->height ? (uint32_t)o->height : s->camera.height;
    pm_camera_setup(&s->camera, c.w, c.h, &c.cam);
    int nthreads = st->threads_used > 0 ? st->threads_used : 1;
    size_t np = (size_t)c.w * c.h;
    ref_accum_t a = {calloc(np * 3, sizeof(double)), calloc(np * 3, sizeof(double)), 0};
    ref_counts_t *cnt = aligned_alloc(64, (size_t)nthreads * sizeof *cnt);
    pm_result_t r = pm_shade_geom_init(s, &c.geom);
    if (r == PM_OK && (!a.mean || !a.m2 || !cnt))
        r = pm_error_set(PM_ERR_NOMEM, "out of memory for a %" PRIu32 "x%" PRIu32 " image", c.w, c.h);
    if (r == PM_OK)
        memset(cnt, 0, (size_t)nthreads * sizeof *cnt);
    if (r == PM_OK && o->resume)
        r = resume(&c, o->resume, &a);
    uint64_t resumed = a.n;

    pm_progress_t prog;
    uint64_t todo = (uint64_t)o->spp > a.n ? (uint64_t)o->spp - a.n : 0;
    pm_progress_begin(&prog, "samples", todo, pm_stage_progress(st));
    double t0 = pm_time_wall(), t_write = 0.0;
    int passes = 0, timed_out = 0;
    while (r == PM_OK && a.n < (uint64_t)o->spp) {
        if (o->time_s > 0.0 && passes > 0 && pm_time_wall() - t0 >= o->time_s) {
            timed_out = 1;
            break;
        }
        uint64_t k1 = a.n + (uint64_t)o->pass < (uint64_t)o->spp ? a.n + (uint64_t)o->pass : (uint64_t)o->spp;
        uint64_t k0 = a.n;
        run_pass(&c, &a, (uint32_t)k0, (uint32_t)k1, nthreads, cnt);
        passes++;
        pm_progress_add(&prog, k1 - k0);
        double tw = pm_time_wall();
        r = write_outputs(st, o, &c, &a);
        t_write += pm_time_wall() - tw;
    }
    double t_all = pm_time_wall() - t0, t_trace = t_all - t_write;
    pm_progress_end(&prog);
    if (r == PM_OK && passes == 0)
        r = write_outputs(st, o, &c, &a); /* already at --spp: the outputs say so */

    ref_counts_t sum = {0};
    for (int i = 0; i < nthreads && cnt; i++) {
        sum.paths += cnt[i].paths, sum.rays += cnt[i].rays, sum.shadow_rays += cnt[i].shadow_rays;
        sum.capped += cnt[i].capped, sum.nonfinite += cnt[i].nonfinite;
        if (cnt[i].longest > sum.longest)
            sum.longest = cnt[i].longest;
    }
    if (r == PM_OK) {
        double rmse, mean, rel;
        image_error(&c, &a, &rmse, &mean, &rel);
        uint64_t rays = sum.rays + sum.shadow_rays;
        pm_stage_stat_int(st, "width", c.w);
        pm_stage_stat_int(st, "height", c.h);
        pm_stage_stat_int(st, "samples", (int64_t)a.n);
        pm_stage_stat_int(st, "samples_resumed", (int64_t)resumed);
        pm_stage_stat_int(st, "passes", passes);
        pm_stage_stat_int(st, "timed_out", timed_out);
        pm_stage_stat_int(st, "paths", (int64_t)sum.paths);
        pm_stage_stat_int(st, "rays", (int64_t)sum.rays);
        pm_stage_stat_int(st, "shadow_rays", (int64_t)sum.shadow_rays);
        pm_stage_stat_double(st, "rays_per_s", t_trace > 0 ? (double)rays / t_trace : 0.0);
        pm_stage_stat_double(st, "rays_per_path", sum.paths ? (double)sum.rays / (double)sum.paths : 0.0);
        pm_stage_stat_int(st, "longest_path", (int64_t)sum.longest);
        pm_stage_stat_int(st, "capped_paths", (int64_t)sum.capped);
        pm_stage_stat_int(st, "nonfinite_samples", (int64_t)sum.nonfinite);
        pm_stage_stat_double(st, "trace_s", t_trace);
        pm_stage_stat_double(st, "write_s", t_write);
        pm_stage_stat_double(st, "mean_radiance", mean);
        pm_stage_stat_double(st, "stderr_rms", rmse);
        pm_stage_stat_double(st, "stderr_rel", rel);
        st->items = sum.paths;
        pm_stage_note(st, "%" PRIu64 " samples per pixel (%d passes, %.3f s, %.2f Mrays/s); standard error %.3g W/(m^2 sr) "
                      "RMS, %.3g%% of the mean%s",
                      a.n, passes, t_trace, t_trace > 0 ? 1e-6 * (double)rays / t_trace : 0.0, rmse, 100.0 * rel,
                      timed_out ? " (stopped by --time)" : "");
        if (sum.capped)
            pm_stage_note(st, "warning: %" PRIu64 " paths reached --max-bounces %u and were cut (biased low)", sum.capped,
                          c.max_bounces);
        if (sum.nonfinite)
            pm_stage_note(st, "warning: %" PRIu64 " samples were not finite and were dropped", sum.nonfinite);
    }
    free(a.mean);
    free(a.m2);
    free(cnt);
    pm_shade_geom_free(&c.geom);
    return r;
}

int main(int argc, char **argv)
{
    pm_stage_t st;
    pm_stage_defaults(&st);
    ref_options_t o = {.spp = 64, .pass = 16, .max_bounces = 1 << 20, .rr_start = 3};
    const pm_option_t options[] = {
        PM_STAGE_COMMON_OPTIONS(st),
        {"spp", 0, PM_OPT_INT, &o.spp, "N", "samples (paths) per pixel in all, resumed ones included", 1, 4e9, NULL},
        {"pass", 0, PM_OPT_INT, &o.pass, "N", "samples per pixel per pass; the outputs are rewritten after each", 1, 4e9,
         NULL},
        {"time", 0, PM_OPT_DOUBLE, &o.time_s, "S",
         "stop after S seconds, at the end of a pass (at least one pass runs); 0: no limit", 0, 1e9, NULL},
        {"radiance", 0, PM_OPT_STRING, &o.radiance, "FILE",
         "also write the f64 radiance buffer with each pixel's variance (for measure-error and --resume)", 1, 0, NULL},
        {"resume", 0, PM_OPT_STRING, &o.resume, "FILE",
         "continue the samples of an earlier --radiance FILE of the same scene, size, seed and pixel", 1, 0, NULL},
        {"pixel", 0, PM_OPT_CHOICE, &o.pixel, "HOW",
         "center: through pixel centres, as trace-gather-points with --primary 1; box: uniform over the pixel", 1, 0,
         pixel_names},
        {"component", 0, PM_OPT_CHOICE, &o.component, "WHICH",
         "total, or only direct (emission seen and direct light: trace-gather-points --direct) or indirect "
         "(simd-gather's part)", 1, 0, component_names},
        {"width", 0, PM_OPT_INT, &o.width, "N", "image width in pixels; 0 takes the scene camera's", 0, 65536, NULL},
        {"height", 0, PM_OPT_INT, &o.height, "N", "image height in pixels; 0 takes the scene camera's", 0, 65536, NULL},
        {"max-bounces", 0, PM_OPT_INT, &o.max_bounces, "N",
         "safety net: cut a path after N bounces (counted in --stats; Russian roulette ends paths first)", 1, 1e9,
         NULL},
        {"rr-start", 0, PM_OPT_INT, &o.rr_start, "N", "bounces before Russian roulette may end a path", 0, 1e9, NULL},
        {0},
    };
    const pm_cli_t cli = {"trace-reference", "[options] SCENE [-o] OUT.exr",
                          "Render a reference image with an unbiased path tracer (next-event estimation, MIS, "
                          "Russian roulette) over the photon stages' scene model; progressive.",
                          options, 1, 2};
    int rc = pm_stage_begin(&st, &cli, argc, argv);
    if (rc >= 0)
        return rc;
    if (st.args.nargs == 2) {
        if (strcmp(st.output, "-"))
            return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "give the output once: as -o or as the second argument"));
        st.output = st.args.args[1];
    }
    if (!strcmp(st.output, "-"))
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "an OpenEXR output needs a file name (OpenEXR cannot "
                                                            "write to a pipe): -o OUT.exr"));
    if (o.radiance && (!strcmp(o.radiance, "-") || !strcmp(o.radiance, st.output)))
        return pm_stage_end(&st, pm_error_set(PM_ERR_USAGE, "--radiance needs a file of its own"));
    pm_scene_t s;
    pm_result_t r = pm_scene_load(st.args.args[0], &s);
    if (r != PM_OK)
        return pm_stage_end(&st, r);
    double power[3];
    pm_scene_power(&s, power);
    if (!(power[0] + power[1] + power[2] > 0.0)) {
        r = pm_error_set(PM_ERR_INPUT, "scene '%s' has no lights (%zu point lights and %zu emissive triangles emit 0 W): "
                         "its reference image is black", s.path, s.nlights, s.nemissive);
        pm_scene_free(&s);
        return pm_stage_end(&st, r);
    }
    pm_rt_t rt;
    r = pm_rt_create(&s, 1, st.threads_used, &rt);
    if (r == PM_OK)
        r = run(&st, &o, &s, &rt);
    pm_rt_destroy(&rt);
    pm_scene_free(&s);
    return pm_stage_end(&st, r);
}
