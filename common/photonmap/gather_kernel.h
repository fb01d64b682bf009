/* gather_kernel.h: the packet traversal and shading of the gather, written once for every
 * SIMD width. Included by gather_isa.c once per ISA, with these defined:
 *
 *   W            lanes (1, 4, 8, 16)           FN(x)        name suffix for this ISA and VAR
 *   VAR          0: one fixed width h; 1: per-photon widths (the map's width channel);
 *                2: per-query widths (the queries' radius array, the library's API)
 *   V            the vector type               VSET1(x), VLOAD(p), VSTORE(p, v), VADD,
 *   VSUB, VMUL, VFMA(a, b, c) = a b + c        BLE(a, b), BLT, BGE: lane bits of a <= b, ...
 *   VMASKED(bits, v): v in the lanes of bits, 0 elsewhere; VSQRTF(x): the square root of a VF
 *   (W > 1); FLUSH(ar, ag, ab, dacc): adds the
 *   float accumulators to the double ones (every GATHER_FLUSH shading steps, so that a
 *   million photons summed into one query keep their digits)
 *
 * The walk follows the paper's pseudocode (section 5.3): the packet descends with a lane
 * mask; at an inner node a lane stays live on the left when its sphere reaches below the
 * plane and on the right when it reaches above; the node's photon (which lies on the plane)
 * is shaded for the lanes live on both sides, and the shading applies the exact distance
 * and normal tests per lane. Planes are compared with a radius grown by the map's
 * coordinate slack (the split value differs from the photon's coordinate in its low 2
 * mantissa bits), so no photon in reach is ever skipped. */

#if W > 1
/* x^n for every lane, x <= 0 giving 0 (the Phong lobe's max(0, cos)^ns): exp2(n log2 x)
 * in float, with log2 from the atanh series on a mantissa in [sqrt(1/2), sqrt(2)) and
 * exp2 from its Taylor series on (-1/2, 1/2]; about 1e-7 relative for log2, so the power is
 * good to about 1e-7 times |ln x^n|. Written with GCC's vector extensions (VF, VI), which
 * compile to this ISA's instructions. */
static inline VF FN(vpow)(VF x, VF n)
{
    const VF one = (VF){0} + 1.0f;
    VI pos = x > 0.0f;
    VF xs = (VF)(((VI)x & pos) | ((VI)one & ~pos));
    VI bits = (VI)xs;
    VI e = ((bits >> 23) & 0xff) - 127;
    VF mnt = (VF)((bits & 0x7fffff) | 0x3f800000);
    VI big = mnt > 1.41421356f;
    mnt = (VF)(((VI)(mnt * 0.5f) & big) | ((VI)mnt & ~big));
    e = e - big; /* big is -1 where true */
    VF t = (mnt - 1.0f) / (mnt + 1.0f), t2 = t * t;
    VF lg = t * (2.8853900817779268f +
                 t2 * (0.9617966939259756f +
                       t2 * (0.5770780163555854f + t2 * (0.4121985831111324f + t2 * 0.3205988979753252f))));
    VF y = n * (__builtin_convertvector(e, VF) + lg);
    VI under = y < -126.0f;
    y = (VF)(((VI)y & ~under) | ((VI)((VF){0} - 126.0f) & under));
    VI i = -__builtin_convertvector(0.5f - y, VI); /* round: 0.5 - y > 0 unless y > 0.5 */
    VF f = y - __builtin_convertvector(i, VF);
    VF p =
        1.0f +
        f * (0.6931471805599453f +
             f * (0.2402265069591007f +
                  f * (0.05550410866482158f +
                       f * (0.009618129107628477f +
                            f * (0.0013333558146428443f + f * (1.5403530393381608e-4f + f * 1.525273380405984e-5f))))));
    VF r = p * (VF)((i + 127) << 23);
    return (VF)((VI)r & ~under & pos);
}

/* Lane selection and the small functions of physics/bsdf.c, on VF. */
static inline VF FN(vsel)(VI m, VF a, VF b) { return (VF)(((VI)a & m) | ((VI)b & ~m)); }
static inline VF FN(vmin)(VF a, VF b) { return FN(vsel)(a < b, a, b); }
static inline VF FN(vmax)(VF a, VF b) { return FN(vsel)(a > b, a, b); }
static inline VF FN(vabs)(VF a) { return (VF)((VI)a & 0x7fffffff); }
static inline VI FN(vbits)(uint32_t bits)
{
    _Alignas(64) int32_t t[W];
    for (int l = 0; l < W; l++)
        t[l] = -(int32_t)((bits >> l) & 1u);
    return *(const VI *)t;
}

/* pm_fresnel_dielectric(cos_i, eta) for eta in [PM_ETA_MIN, PM_ETA_MAX] (callers clamp). */
static inline VF FN(vfresnel_dielectric)(VF cos_i, VF eta)
{
    const VF one = (VF){0} + 1.0f;
    VF ci = FN(vmin)(FN(vabs)(cos_i), one);
    VI total = ~(ci > 0.0f);
    VF sin_t2 = (1.0f - ci * ci) / (eta * eta);
    total |= sin_t2 >= 1.0f;
    VF ct = VSQRTF(FN(vmax)(1.0f - sin_t2, (VF){0}));
    VF rs = (ci - eta * ct) / (ci + eta * ct), rp = (eta * ci - ct) / (eta * ci + ct);
    VF f = FN(vmin)(one, 0.5f * (rs * rs + rp * rp));
    return FN(vsel)(total, one, f);
}

/* pm_fresnel_conductor(cos_i, eta, k) in float: the unpolarized reflectance of the complex index
 * eta + i k written with a^2 + b^2 = |N^2 - sin^2| (the module works in double complex; the two
 * agree to about 1e-6 for the indices of metals, tests/unit/test_gather.c). */
static inline VF FN(vfresnel_conductor)(VF cos_i, VF eta, VF k)
{
    const VF one = (VF){0} + 1.0f;
    VF c = FN(vmin)(FN(vabs)(cos_i), one), c2 = c * c, s2 = 1.0f - c2;
    VF t0 = eta * eta - k * k - s2, ab2 = VSQRTF(t0 * t0 + 4.0f * eta * eta * k * k);
    VF a = VSQRTF(FN(vmax)(0.5f * (ab2 + t0), (VF){0}));
    VF t1 = ab2 + c2, t2 = 2.0f * a * c, rs = (t1 - t2) / (t1 + t2);
    VF t3 = c2 * ab2 + s2 * s2, t4 = t2 * s2, rp = rs * (t3 - t4) / (t3 + t4);
    VF r = FN(vmin)(FN(vmax)(0.5f * (rs + rp), (VF){0}), one);
    return FN(vsel)(c > 0.0f, r, one);
}

/* f(wi, wo) of the GGX lanes (conductor, plastic; GL_KIND_* of gather_impl.h) for the photon
 * direction win, as pm_bsdf_eval computes it: the normal on wo's side (set up per lane), D of
 * the half vector, Smith's height-correlated G2, the conductor's Fresnel at wo.h, or the
 * plastic's coat (dielectric Fresnel at wo.h) over its base. Lanes of other kinds get garbage
 * the caller selects away. */
static inline void FN(ggx_eval)(float (*gl)[W], float (*lwo)[W], const float win[3], VF f[3])
{
    const VF one = (VF){0} + 1.0f, zero = (VF){0};
    VF nx = *(const VF *)gl[GL_N], ny = *(const VF *)gl[GL_N + 1], nz = *(const VF *)gl[GL_N + 2];
    VF wx = *(const VF *)lwo[0], wy = *(const VF *)lwo[1], wz = *(const VF *)lwo[2];
    VF co = *(const VF *)gl[GL_CO], a2 = *(const VF *)gl[GL_A2], kind = *(const VF *)gl[GL_KIND];
    VF ci = nx * win[0] + ny * win[1] + nz * win[2];
    VI side = (ci > 0.0f) & (co > 0.0f); /* reflect_side: both strictly above */
    VF hx = win[0] + wx, hy = win[1] + wy, hz = win[2] + wz;
    VF l = VSQRTF(hx * hx + hy * hy + hz * hz);
    VI okh = side & (l > 1e-12f);
    l = FN(vsel)(okh, l, one);
    VF ch = (nx * hx + ny * hy + nz * hz) / l, wh = (wx * hx + wy * hy + wz * hz) / l;
    okh &= wh > 0.0f;
    /* pm_ggx_d */
    VF c2 = FN(vmin)(ch * ch, one), t = c2 * (a2 - 1.0f) + 1.0f;
    VF d = FN(vsel)(ch > 0.0f, a2 / (3.14159265358979323846f * t * t), zero);
    /* pm_ggx_lambda at wi, and G2 with wo's (set up per lane) */
    VF cc = FN(vmin)(FN(vmax)(FN(vabs)(ci), (VF){0} + 1e-7f), one), s2 = 1.0f - cc * cc;
    VF sq = VSQRTF(cc * cc + a2 * s2), lam = a2 * s2 / (2.0f * cc * (sq + cc));
    VF g2 = 1.0f / (1.0f + lam + *(const VF *)gl[GL_LO]);
    VF core = d * g2 / (4.0f * FN(vsel)(side, ci, one) * FN(vsel)(side, co, one));
    VI spec = okh & (core > 0.0f);
    core = FN(vsel)(spec, core, zero);
    VI plastic = kind == (float)GL_KIND_PLASTIC, schlick = kind == (float)GL_KIND_SCHLICK;
    VF ior = FN(vsel)(plastic, *(const VF *)gl[GL_IOR], one);
    VF fcoat = FN(vfresnel_dielectric)(wh, ior) * core;
    VF ti = 1.0f - FN(vfresnel_dielectric)(ci, ior);
    VF m = 1.0f - FN(vmin)(FN(vabs)(wh), one), m2 = m * m, m5 = m2 * m2 * m; /* pm_fresnel_schlick's */
    for (int k = 0; k < 3; k++) {
        VF e = *(const VF *)gl[GL_E + k];
        VF fr = FN(vsel)(schlick, e + (1.0f - e) * m5, FN(vfresnel_conductor)(wh, e, *(const VF *)gl[GL_K + k]));
        VF fp = FN(vsel)(side, *(const VF *)gl[GL_KD + k] * ti, zero) + fcoat;
        f[k] = FN(vsel)(plastic, fp, FN(vsel)(spec, fr * core, zero));
    }
}
#endif

#if W > 1
/* The glossy lanes of the packet at query b: their outgoing directions into lwo (0 elsewhere)
 * and their materials' rows into gl (gather_lane_setup); *ggx_out the lanes of a GGX kind,
 * *slow_out those the module evaluates itself. */
static void FN(glossy_lanes)(const gather_ctx_t *c, uint64_t b, uint32_t glossy, float (*gl)[W], float (*lwo)[W],
                             uint32_t *ggx_out, uint32_t *slow_out)
{
    const pm_gather_queries_t *q = c->q;
    uint32_t ggx = 0, slow = 0;
    memset(gl, 0, GL_ROWS * W * sizeof(float));
    for (uint32_t l = 0; l < W; l++)
        for (int k = 0; k < 3; k++)
            lwo[k][l] = (glossy >> l & 1) ? q->dir[3 * (b + l) + k] : 0.0f;
    for (uint32_t g = glossy; g; g &= g - 1) {
        uint32_t l = (uint32_t)__builtin_ctz(g), mi = q->material ? q->material[b + l] : 0;
        float wo[3] = {lwo[0][l], lwo[1][l], lwo[2][l]};
        int kind = gather_lane_setup(c, &q->materials[mi], mi, &q->normal[3 * (b + l)], wo, &gl[0][0], W, l);
        ggx |= (uint32_t)(kind != GL_KIND_PHONG && kind != GL_KIND_MODULE) << l;
        slow |= (uint32_t)(kind == GL_KIND_MODULE) << l;
    }
    *ggx_out = ggx, *slow_out = slow;
}

/* f of every glossy lane at once for the photon direction win (toward its source), each lane
 * with its own material, as physics/bsdf.h's pm_bsdf_eval: Phong lanes f = kd/pi + ks (ns + 2)/(2 pi)
 * max(0, r(wi) . wo)^ns where n.wi > 0, the GGX lanes (ggx, 0 when none is hit) by ggx_eval. */
static inline void FN(glossy_f)(float (*gl)[W], float (*lwo)[W], VF vnx, VF vny, VF vnz, const float *win, uint32_t ggx,
                                VF f[3])
{
    VF cw = vnx * win[0] + vny * win[1] + vnz * win[2];
    VF rx = 2.0f * cw * vnx - win[0], ry = 2.0f * cw * vny - win[1], rz = 2.0f * cw * vnz - win[2];
    VF cr = rx * *(const VF *)lwo[0] + ry * *(const VF *)lwo[1] + rz * *(const VF *)lwo[2];
    VF ns = *(const VF *)gl[GL_NS];
    VF lobe = FN(vpow)(cr, ns) * ((ns + 2.0f) * 0.15915494309189535f);
    VI above = cw > 0.0f;
    for (int k = 0; k < 3; k++)
        f[k] = FN(vsel)(above, *(const VF *)gl[GL_KD + k] + *(const VF *)gl[GL_KS + k] * lobe, (VF){0});
    if (ggx) {
        VF fg[3];
        VI gm = FN(vbits)(ggx);
        FN(ggx_eval)(gl, lwo, win, fg);
        for (int k = 0; k < 3; k++)
            f[k] = FN(vsel)(gm, fg[k], f[k]);
    }
}
#endif

static void FN(gather_packets)(const gather_ctx_t *c, uint64_t begin, uint64_t end, double *out, pm_gather_stats_t *st)
{
    const pm_gather_map_t *m = c->m;
    const pm_gather_queries_t *q = c->q;
    const pm_gather_hot_t *hot = m->hot;
    const float *pnor = m->normal, *ppow = m->power;
    uint64_t ops = 0, steps = 0, lanes = 0, straddling = 0, visits = 0, packets = 0;
    const uint32_t full = W == 32 ? 0xffffffffu : (1u << W) - 1u;
#if VAR == 0
    const V rt = VSET1(c->r_trav), nrt = VSET1(-c->r_trav), r2 = VSET1(c->r2);
    const V kscale = VSET1(c->kscale), kinv = VSET1(c->inv_r2);
#endif
    const V ncos = VSET1(c->normal_cos), one = VSET1(1.0f);
    const int epan = c->kernel == PM_KERNEL_EPANECHNIKOV;

    for (uint64_t b = begin; b < end; b += W) {
        uint32_t nl = end - b < (uint64_t)W ? (uint32_t)(end - b) : (uint32_t)W;
        _Alignas(64) float lq[6][W];
        uint32_t glossy = 0; /* lanes whose material needs f per pair */
        for (uint32_t l = 0; l < W; l++) {
            uint64_t i = b + (l < nl ? l : 0); /* idle lanes repeat lane 0: valid numbers */
            for (int k = 0; k < 3; k++) {
                lq[k][l] = q->pos[3 * i + k];
                lq[3 + k][l] = q->normal[3 * i + k];
            }
            if (c->glossy && l < nl && c->mat_glossy[q->material ? q->material[i] : 0])
                glossy |= 1u << l;
        }
#if W > 1
        /* Glossy lanes: their material and outgoing direction, as vectors for the SIMD f
         * (gather_impl.h's GL_ rows); ggx: the lanes of a GGX kind, slow: those the module
         * evaluates itself, pair by pair. */
        _Alignas(64) float gl[GL_ROWS][W];
        _Alignas(64) float lwo[3][W];
        uint32_t ggx = 0, slow = 0;
        if (glossy)
            FN(glossy_lanes)(c, b, glossy, gl, lwo, &ggx, &slow);
#endif
#if VAR == 2
        /* Per-query widths: each lane's own h, h grown by the slack, h^2, 1/h^2 and K(0)/h^2;
         * the walk and the shading are those of one fixed width, lane by lane. */
        _Alignas(64) float lr[5][W];
        for (uint32_t l = 0; l < W; l++) {
            float h = q->radius[b + (l < nl ? l : 0)], h2 = h * h;
            lr[0][l] = h + c->slack;
            lr[1][l] = -(h + c->slack);
            lr[2][l] = h2;
            lr[3][l] = 1.0f / h2;
            lr[4][l] = c->kscale_unit * lr[3][l]; /* as gather.c's fixed kscale, to the bit */
        }
        const V rt = VLOAD(lr[0]), nrt = VLOAD(lr[1]), r2 = VLOAD(lr[2]), kinv = VLOAD(lr[3]), kscale = VLOAD(lr[4]);
#endif
        const V qx = VLOAD(lq[0]), qy = VLOAD(lq[1]), qz = VLOAD(lq[2]);
        const V nx = VLOAD(lq[3]), ny = VLOAD(lq[4]), nz = VLOAD(lq[5]);
        V qa[3] = {qx, qy, qz};
        uint32_t active = nl == W ? full : (1u << nl) - 1u;
        V ar = VSET1(0.0f), ag = VSET1(0.0f), ab = VSET1(0.0f);
        _Alignas(64) double dacc[3][W];
        memset(dacc, 0, sizeof dacc);
        uint32_t since_flush = 0;
        packets++;

        struct {
            uint32_t node, mask;
        } stack[PM_KD_MAX_DEPTH + 1];
        int sp = 0;
        uint32_t ni = 0, mask = m->n ? active : 0;
        while (mask) {
            visits++;
            const pm_gather_hot_t *hp = &hot[ni];
            const uint32_t link = hp->link;
            uint32_t axis = link >> 30, shade = mask, straddle = mask, ml = 0, mr = 0, right = PM_KD_NONE;
#if VAR == 1
            const float wi = m->width[ni];
#endif
            if (axis != PM_KD_LEAF) {
                V dist = VSUB(qa[axis], VSET1(hp->p[axis]));
                uint32_t child = link & PM_GATHER_NO_CHILD;
                int has_left = child != ni + 1;
                right = child == PM_GATHER_NO_CHILD ? PM_KD_NONE : child; /* child == ni + 1: right only */
#if VAR == 1
                float wl = has_left ? m->subtree_width[ni + 1] + c->slack : 0.0f;
                float wr = right != PM_KD_NONE ? m->subtree_width[right] + c->slack : 0.0f;
                float ws = wi + c->slack;
                ml = has_left ? mask & BLE(dist, VSET1(wl)) : 0;
                mr = right != PM_KD_NONE ? mask & BGE(dist, VSET1(-wr)) : 0;
                shade = mask & BLE(dist, VSET1(ws)) & BGE(dist, VSET1(-ws));
#else
                ml = mask & BLE(dist, rt);
                mr = mask & BGE(dist, nrt);
                /* Only a lane live on both sides can reach the plane's photon; when one does,
                 * the photon is shaded for the packet's live lanes, as ShadeCurrentNode of the
                 * paper does, and the exact test sorts them out. */
                straddle = ml & mr;
                shade = straddle ? mask : 0;
                ml = has_left ? ml : 0;
                mr = right != PM_KD_NONE ? mr : 0;
#endif
            }
            if (shade) {
                const float *pp = hp->p;
                V dx = VSUB(qx, VSET1(pp[0])), dy = VSUB(qy, VSET1(pp[1])), dz = VSUB(qz, VSET1(pp[2]));
                V d2 = VFMA(dx, dx, VFMA(dy, dy, VMUL(dz, dz)));
#if VAR == 1
                const float h2 = wi * wi;
                uint32_t hit = shade & BLT(d2, VSET1(h2));
#else
                uint32_t hit = shade & BLT(d2, r2);
#endif
                steps++;
                lanes += (uint64_t)__builtin_popcount(shade);
                straddling += (uint64_t)__builtin_popcount(straddle);
                if (hit) {
                    const float *pn = &pnor[3 * (size_t)ni];
                    V dot = VFMA(nx, VSET1(pn[0]), VFMA(ny, VSET1(pn[1]), VMUL(nz, VSET1(pn[2]))));
                    hit &= BGE(dot, ncos);
                }
                if (hit) {
                    ops += (uint64_t)__builtin_popcount(hit);
#if VAR == 1
                    const float ks = c->kscale_unit / h2, ki = 1.0f / h2;
                    V kv = epan ? VMUL(VSET1(ks), VSUB(one, VMUL(d2, VSET1(ki)))) : VSET1(ks);
#else
                    V kv = epan ? VMUL(kscale, VSUB(one, VMUL(d2, kinv))) : kscale;
#endif
                    const float *pw = &ppow[3 * (size_t)ni];
                    uint32_t diffuse = hit & ~glossy;
                    if (diffuse) {
                        V kd = VMASKED(diffuse, kv);
                        ar = VFMA(kd, VSET1(pw[0]), ar);
                        ag = VFMA(kd, VSET1(pw[1]), ag);
                        ab = VFMA(kd, VSET1(pw[2]), ab);
                        if (++since_flush >= GATHER_FLUSH) {
                            FLUSH(ar, ag, ab, dacc);
                            ar = ag = ab = VSET1(0.0f);
                            since_flush = 0;
                        }
                    }
                    if (hit & glossy) {
#if W > 1
                        /* f for every glossy lane at once (glossy_f), each with its own material */
                        VF f[3];
                        FN(glossy_f)(gl, lwo, (VF)nx, (VF)ny, (VF)nz, &m->dir[3 * (size_t)ni], hit & ggx ? ggx : 0, f);
                        V kg = VMASKED(hit & glossy & ~slow, kv);
                        ar = VFMA(VMUL(kg, (V)f[0]), VSET1(pw[0]), ar);
                        ag = VFMA(VMUL(kg, (V)f[1]), VSET1(pw[1]), ag);
                        ab = VFMA(VMUL(kg, (V)f[2]), VSET1(pw[2]), ab);
                        if (++since_flush >= GATHER_FLUSH) {
                            FLUSH(ar, ag, ab, dacc);
                            ar = ag = ab = VSET1(0.0f);
                            since_flush = 0;
                        }
                        if (hit & slow) {
                            _Alignas(64) float kl[W];
                            VSTORE(kl, kv);
                            for (uint32_t g = hit & slow; g; g &= g - 1) {
                                uint32_t l = (uint32_t)__builtin_ctz(g);
                                gather_glossy_lane(c, b + l, ni, kl[l], &dacc[0][0], W, l);
                            }
                        }
#else
                        gather_glossy_lane(c, b, ni, kv, &dacc[0][0], 1, 0);
#endif
                    }
                }
            }
            if (ml) {
                if (mr) {
                    stack[sp].node = right;
                    stack[sp].mask = mr;
                    sp++;
                }
                ni = ni + 1;
                mask = ml;
                continue;
            }
            if (mr) {
                ni = right;
                mask = mr;
                continue;
            }
            if (!sp)
                break;
            sp--;
            ni = stack[sp].node;
            mask = stack[sp].mask;
        }
        FLUSH(ar, ag, ab, dacc);
        for (uint32_t l = 0; l < nl; l++) {
            const float *w = q->weight ? &q->weight[3 * (b + l)] : NULL; /* NULL: weights of 1 */
            double *o = &out[3 * (b + l - begin)];
            for (int k = 0; k < 3; k++)
                o[k] = w ? dacc[k][l] * w[k] : dacc[k][l];
        }
    }
    st->shader_ops += ops;
    st->shade_steps += steps;
    st->active_lanes += lanes;
    st->straddling_lanes += straddling;
    st->nodes_visited += visits;
    st->packets += packets;
}
