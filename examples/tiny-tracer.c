/* tiny-tracer: a renderer outside pmtk that uses the installed libpmtk for its photon map.
 *
 * Its own tracer: a closed box of five diffuse walls (a red left wall, a green right one, the
 * rest grey, the camera looking in through the open side) lit by a point light under the
 * ceiling. Photons are traced from the light with Russian roulette and stored at every
 * diffuse hit; the camera's rays make one query per pixel at their first hit; libpmtk builds
 * the KD-tree, Hilbert-orders the queries, and gathers them in SIMD packets with the
 * sample-point estimator; the image (the estimate times the wall's albedo over pi) is written
 * as a binary PPM.
 *
 *   tiny-tracer [-o IMAGE.ppm] [-n PHOTONS] [-s SIDE] [-r RADIUS]
 *   tiny-tracer --gather MAP.pm QUERIES.pm RADIUS [RUNS]
 *
 * The second form gathers a pmtk photon map and queries file (build-photonmap's and
 * hilbert-sort's) through the API and prints the best wall time of RUNS gathers, to compare
 * with simd-gather on the same files (docs/api.md, "Speed").
 *
 * Build against the installed library:
 *   cc -O2 tiny-tracer.c $(pkg-config --cflags --libs pmtk) -lm -o tiny-tracer */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <pmtk.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- the scene: the box [0,1]^3 open at z = 1, walls by axis and side ---- */
typedef struct {
    int axis; /* 0 x, 1 y, 2 z */
    float at; /* the plane's coordinate */
    float n;  /* +1 or -1: the inward normal's sign on the axis */
    float albedo[3];
} wall_t;

static const wall_t walls[5] = {
    {0, 0.0f, +1.0f, {0.63f, 0.06f, 0.05f}}, /* left, red */
    {0, 1.0f, -1.0f, {0.14f, 0.45f, 0.09f}}, /* right, green */
    {1, 0.0f, +1.0f, {0.72f, 0.72f, 0.72f}}, /* floor */
    {1, 1.0f, -1.0f, {0.72f, 0.72f, 0.72f}}, /* ceiling */
    {2, 0.0f, +1.0f, {0.72f, 0.72f, 0.72f}}, /* back */
};

/* The first wall a ray from o along d (unit) hits inside the box: its index, or -1. */
static int hit(const float o[3], const float d[3], float p_out[3])
{
    int best = -1;
    float tbest = INFINITY;
    for (int w = 0; w < 5; w++) {
        const wall_t *wl = &walls[w];
        if (d[wl->axis] * wl->n >= 0.0f)
            continue; /* moving away from this wall */
        float t = (wl->at - o[wl->axis]) / d[wl->axis];
        if (!(t > 1e-5f) || t >= tbest)
            continue;
        float p[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
        int inside = 1;
        for (int k = 0; k < 3; k++)
            inside &= k == wl->axis || (p[k] >= -1e-4f && p[k] <= 1.0f + 1e-4f);
        if (inside)
            best = w, tbest = t, memcpy(p_out, p, sizeof p);
    }
    return best;
}

static uint64_t rng_state = 0x9e3779b97f4a7c15ull;
static float rnd(void) /* xorshift64*: the example's own, enough for a picture */
{
    rng_state ^= rng_state >> 12, rng_state ^= rng_state << 25, rng_state ^= rng_state >> 27;
    return (float)((rng_state * 0x2545f4914f6cdd1dull) >> 40) * 0x1p-24f;
}

/* A cosine-distributed direction about the inward normal of wall w. */
static void cosine_dir(int w, float d[3])
{
    float u = rnd(), v = rnd(), r = sqrtf(u), phi = 6.2831853f * v;
    float a = r * cosf(phi), b = r * sinf(phi), c = sqrtf(1.0f - u);
    int ax = walls[w].axis;
    d[ax] = c * walls[w].n;
    d[(ax + 1) % 3] = a;
    d[(ax + 2) % 3] = b;
}

static void normal_of(int w, float n[3])
{
    n[0] = n[1] = n[2] = 0.0f;
    n[walls[w].axis] = walls[w].n;
}

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void on_error(void *user, pmtk_result_t code, const char *message)
{
    (void)user;
    fprintf(stderr, "tiny-tracer: %s (%s)\n", message, pmtk_result_string(code));
}

/* The --gather form: best of runs gathers of a pmtk queries file against a photon map file. */
static int gather_files(pmtk_context_t *ctx, const char *map_path, const char *q_path, double radius, int runs)
{
    pmtk_photonmap_t *map = NULL;
    pmtk_file_t *qf = NULL;
    if (pmtk_photonmap_read(ctx, map_path, &map) != PMTK_OK || pmtk_file_read(ctx, q_path, &qf) != PMTK_OK)
        return 1;
    pmtk_queries_t q = {.count = pmtk_file_count(qf),
                        .position = pmtk_file_channel(qf, "position", NULL, NULL),
                        .normal = pmtk_file_channel(qf, "normal", NULL, NULL)};
    double *out = malloc((q.count ? q.count : 1) * 3 * sizeof *out);
    pmtk_gather_params_t p;
    pmtk_gather_params_init(&p);
    p.radius = radius;
    pmtk_gather_stats_t st;
    double best = INFINITY, best_cpu = INFINITY;
    int status = 0;
    for (int i = 0; i < runs && !status; i++) {
        double t0 = now();
        status = pmtk_gather(ctx, map, &q, &p, out, &st) != PMTK_OK;
        best = fmin(best, now() - t0);
        best_cpu = fmin(best_cpu, st.cpu_s);
    }
    if (!status)
        printf("gather: %llu queries, %llu photons, radius %g m, %d lanes, best of %d: %.4f s wall, %.4f s CPU in "
               "the kernels, %.3g shader ops/s\n",
               (unsigned long long)q.count, (unsigned long long)pmtk_photonmap_count(map), radius, st.packet_width,
               runs, best, best_cpu, (double)st.shader_ops / best);
    free(out);
    pmtk_file_destroy(qf);
    pmtk_photonmap_destroy(map);
    return status;
}

int main(int argc, char **argv)
{
    const char *out_path = "tiny.ppm";
    long nphotons = 200000, side = 128;
    double radius = 0.03;
    pmtk_context_t *ctx = NULL;
    if (pmtk_context_create(&ctx) != PMTK_OK)
        return 3;
    pmtk_context_set_error_callback(ctx, on_error, NULL);
    if (argc >= 5 && strcmp(argv[1], "--gather") == 0) {
        int status = gather_files(ctx, argv[2], argv[3], atof(argv[4]), argc > 5 ? atoi(argv[5]) : 5);
        pmtk_context_destroy(ctx);
        return status;
    }
    for (int i = 1; i + 1 < argc; i += 2) {
        if (strcmp(argv[i], "-o") == 0)
            out_path = argv[i + 1];
        else if (strcmp(argv[i], "-n") == 0)
            nphotons = atol(argv[i + 1]);
        else if (strcmp(argv[i], "-s") == 0)
            side = atol(argv[i + 1]);
        else if (strcmp(argv[i], "-r") == 0)
            radius = atof(argv[i + 1]);
        else {
            fprintf(stderr, "tiny-tracer: unknown option '%s'\n", argv[i]);
            return 2;
        }
    }
    if (nphotons < 1 || nphotons > 50000000 || side < 1 || side > 4096 || !(radius > 0.0)) {
        fprintf(stderr, "tiny-tracer: photons %ld, side %ld or radius %g out of range\n", nphotons, side, radius);
        return 2;
    }

    /* Photons: a 10 W white point light, each emitted photon 10/N W, stored at every hit. */
    size_t cap = (size_t)nphotons * 4, n = 0;
    float *pos = malloc(cap * 3 * sizeof *pos), *pow_ = malloc(cap * 3 * sizeof *pow_),
          *nor = malloc(cap * 3 * sizeof *nor);
    const float light[3] = {0.5f, 0.95f, 0.5f};
    for (long e = 0; e < nphotons; e++) {
        float o[3] = {light[0], light[1], light[2]}, d[3], flux[3], p[3];
        for (int k = 0; k < 3; k++)
            flux[k] = 10.0f / (float)nphotons;
        float z = 1.0f - 2.0f * rnd(), r = sqrtf(fmaxf(0.0f, 1.0f - z * z)), phi = 6.2831853f * rnd();
        d[0] = r * cosf(phi), d[1] = r * sinf(phi), d[2] = z;
        for (int bounce = 0; bounce < 8 && n < cap; bounce++) {
            int w = hit(o, d, p);
            if (w < 0)
                break; /* out through the open side */
            memcpy(&pos[3 * n], p, sizeof p);
            memcpy(&pow_[3 * n], flux, sizeof flux);
            normal_of(w, &nor[3 * n]);
            n++;
            float keep = (walls[w].albedo[0] + walls[w].albedo[1] + walls[w].albedo[2]) / 3.0f;
            if (rnd() >= keep)
                break;
            for (int k = 0; k < 3; k++)
                flux[k] *= walls[w].albedo[k] / keep;
            memcpy(o, p, sizeof p);
            cosine_dir(w, d);
        }
    }

    /* Queries: one per pixel, at the first hit of a pinhole camera at z = 2.2. */
    size_t npix = (size_t)(side * side), nq = 0;
    float *qpos = malloc(npix * 3 * sizeof *qpos), *qnor = malloc(npix * 3 * sizeof *qnor);
    uint32_t *qpix = malloc(npix * sizeof *qpix);
    int *qwall = malloc(npix * sizeof *qwall);
    for (long y = 0; y < side; y++)
        for (long x = 0; x < side; x++) {
            float o[3] = {0.5f, 0.5f, 2.2f}, p[3];
            float d[3] = {((float)x + 0.5f) / (float)side - 0.5f, 0.5f - ((float)y + 0.5f) / (float)side, -1.0f};
            float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            for (int k = 0; k < 3; k++)
                d[k] /= l;
            /* enter the box through the open side */
            float t = (1.0f - o[2]) / d[2];
            for (int k = 0; k < 3; k++)
                o[k] += t * d[k];
            int w = hit(o, d, p);
            if (w < 0)
                continue;
            memcpy(&qpos[3 * nq], p, sizeof p);
            normal_of(w, &qnor[3 * nq]);
            qpix[nq] = (uint32_t)(y * side + x);
            qwall[nq] = w;
            nq++;
        }

    /* libpmtk: the map, the queries in Hilbert order, the packet gather. */
    pmtk_photons_t ph = {.count = n, .position = pos, .power = pow_, .normal = nor};
    pmtk_photonmap_t *map = NULL;
    uint32_t *perm = malloc((nq ? nq : 1) * sizeof *perm);
    float *spos = malloc((nq ? nq : 1) * 3 * sizeof *spos), *snor = malloc((nq ? nq : 1) * 3 * sizeof *snor);
    double *est = malloc((nq ? nq : 1) * 3 * sizeof *est);
    int status = 1;
    double t0 = now();
    if (pmtk_photonmap_build(ctx, &ph, &map) != PMTK_OK)
        goto done;
    double t1 = now();
    if (pmtk_hilbert_order(ctx, qpos, 3 * sizeof(float), nq, 1, perm) != PMTK_OK)
        goto done;
    for (size_t i = 0; i < nq; i++)
        memcpy(&spos[3 * i], &qpos[3 * perm[i]], 12), memcpy(&snor[3 * i], &qnor[3 * perm[i]], 12);
    pmtk_queries_t q = {.count = nq, .position = spos, .normal = snor};
    pmtk_gather_params_t gp;
    pmtk_gather_params_init(&gp);
    gp.radius = radius;
    gp.normal_cos = 0.9f;
    pmtk_gather_stats_t st;
    double t2 = now();
    if (pmtk_gather(ctx, map, &q, &gp, est, &st) != PMTK_OK)
        goto done;
    double t3 = now();

    /* radiance = albedo / pi times the estimate (W/m^2) */
    unsigned char *img = calloc(npix, 3);
    for (size_t i = 0; i < nq; i++) {
        size_t src = perm[i];
        for (int k = 0; k < 3; k++) {
            double L = walls[qwall[src]].albedo[k] / 3.14159265358979323846 * est[3 * i + k];
            double v = 255.0 * pow(fmin(1.0, L * 0.8), 1.0 / 2.2);
            img[3 * (size_t)qpix[src] + k] = (unsigned char)(v + 0.5);
        }
    }
    FILE *f = fopen(out_path, "wb");
    if (!f || fprintf(f, "P6\n%ld %ld\n255\n", side, side) < 0 || fwrite(img, 3, npix, f) != npix || fclose(f) != 0) {
        fprintf(stderr, "tiny-tracer: cannot write '%s'\n", out_path);
        free(img);
        goto done;
    }
    free(img);
    printf("tiny-tracer: %zu photons (map %.3f s), %zu queries gathered in %.3f s on %s (%d lanes), %s\n", n, t1 - t0,
           nq, t3 - t2, pmtk_isa_name(pmtk_isa_best()), st.packet_width, out_path);
    status = 0;
done:
    pmtk_photonmap_destroy(map);
    pmtk_context_destroy(ctx);
    free(pos), free(pow_), free(nor), free(qpos), free(qnor), free(qpix), free(qwall), free(perm), free(spos),
        free(snor), free(est);
    return status;
}
