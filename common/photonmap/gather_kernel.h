/* gather_kernel.h: the packet traversal and shading of the gather, written once for every
 * SIMD width. Included by gather_isa.c once per ISA, with these defined:
 *
 *   W            lanes (1, 4, 8, 16)           FN(x)        name suffix for this ISA and VAR
 *   VAR          0: one fixed width h; 1: per-photon widths (the map's width channel)
 *   V            the vector type               VSET1(x), VLOAD(p), VSTORE(p, v), VADD,
 *   VSUB, VMUL, VFMA(a, b, c) = a b + c        BLE(a, b), BLT, BGE: lane bits of a <= b, ...
 *   VMASKED(bits, v): v in the lanes of bits, 0 elsewhere; FLUSH(ar, ag, ab, dacc): adds the
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
#endif

static void FN(gather_packets)(const gather_ctx_t *c, uint64_t begin, uint64_t end, double *out, pm_gather_stats_t *st)
{
    const pm_gather_map_t *m = c->m;
    const pm_gather_queries_t *q = c->q;
    const pm_gather_hot_t *hot = m->hot;
    const float *pnor = m->normal, *ppow = m->power;
    uint64_t ops = 0, steps = 0, lanes = 0, straddling = 0, visits = 0, packets = 0;
    const uint32_t full = W == 32 ? 0xffffffffu : (1u << W) - 1u;
#if !VAR
    const V rt = VSET1(c->r_trav), nrt = VSET1(-c->r_trav), r2 = VSET1(c->r2);
#endif
    const V ncos = VSET1(c->normal_cos), one = VSET1(1.0f), kscale = VSET1(c->kscale), kinv = VSET1(c->inv_r2);
    const int epan = c->kernel == PM_KERNEL_EPANECHNIKOV;

    for (uint64_t b = begin; b < end; b += W) {
        uint32_t nl = end - b < (uint64_t)W ? (uint32_t)(end - b) : (uint32_t)W;
        _Alignas(64) float lq[6][W];
        uint32_t glossy = 0; /* lanes whose material needs the full BRDF per pair */
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
        /* Glossy lanes: their material and outgoing direction, as vectors for the SIMD BRDF. */
        _Alignas(64) float gl[8][W];
        if (glossy) {
            memset(gl, 0, sizeof gl);
            for (uint32_t g = glossy; g; g &= g - 1) {
                uint32_t l = (uint32_t)__builtin_ctz(g);
                uint64_t i = b + l;
                const pm_material_t *mt = &q->materials[q->material ? q->material[i] : 0];
                for (int k = 0; k < 3; k++) {
                    gl[k][l] = mt->kd[k] * 0.31830988618379067f; /* kd / pi */
                    gl[3 + k][l] = mt->ks[k];
                }
                gl[6][l] = mt->ns;
            }
        }
        _Alignas(64) float lwo[3][W];
        if (glossy)
            for (uint32_t l = 0; l < W; l++)
                for (int k = 0; k < 3; k++)
                    lwo[k][l] = (glossy >> l & 1) ? q->dir[3 * (b + l) + k] : 0.0f;
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
#if VAR
            const float wi = m->width[ni];
#endif
            if (axis != PM_KD_LEAF) {
                V dist = VSUB(qa[axis], VSET1(hp->p[axis]));
                uint32_t child = link & PM_GATHER_NO_CHILD;
                int has_left = child != ni + 1;
                right = child == PM_GATHER_NO_CHILD ? PM_KD_NONE : child; /* child == ni + 1: right only */
#if VAR
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
#if VAR
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
#if VAR
                    const float ks = c->kscale_unit / h2, ki = 1.0f / h2;
                    V kv = epan ? VMUL(VSET1(ks), VSUB(one, VMUL(d2, VSET1(ki)))) : VSET1(ks);
                    (void)kscale, (void)kinv;
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
                        /* The whole BRDF for every glossy lane at once, each with its own
                         * material: f = kd/pi + ks (ns + 2)/(2 pi) max(0, r(wi) . wo)^ns. */
                        const float *win = &m->dir[3 * (size_t)ni]; /* toward the photon's source */
                        VF vnx = (VF)nx, vny = (VF)ny, vnz = (VF)nz;
                        VF cw = vnx * win[0] + vny * win[1] + vnz * win[2];
                        VF rx = 2.0f * cw * vnx - win[0], ry = 2.0f * cw * vny - win[1], rz = 2.0f * cw * vnz - win[2];
                        VF cr = rx * *(const VF *)lwo[0] + ry * *(const VF *)lwo[1] + rz * *(const VF *)lwo[2];
                        VF ns = *(const VF *)gl[6];
                        VF lobe = FN(vpow)(cr, ns) * ((ns + 2.0f) * 0.15915494309189535f);
                        V kg = VMASKED(hit & glossy, kv);
                        V fr = (V)(*(const VF *)gl[0] + *(const VF *)gl[3] * lobe);
                        V fg = (V)(*(const VF *)gl[1] + *(const VF *)gl[4] * lobe);
                        V fb = (V)(*(const VF *)gl[2] + *(const VF *)gl[5] * lobe);
                        ar = VFMA(VMUL(kg, fr), VSET1(pw[0]), ar);
                        ag = VFMA(VMUL(kg, fg), VSET1(pw[1]), ag);
                        ab = VFMA(VMUL(kg, fb), VSET1(pw[2]), ab);
                        if (++since_flush >= GATHER_FLUSH) {
                            FLUSH(ar, ag, ab, dacc);
                            ar = ag = ab = VSET1(0.0f);
                            since_flush = 0;
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
            const float *w = &q->weight[3 * (b + l)];
            double *o = &out[3 * (b + l - begin)];
            for (int k = 0; k < 3; k++)
                o[k] = dacc[k][l] * w[k];
        }
    }
    st->shader_ops += ops;
    st->shade_steps += steps;
    st->active_lanes += lanes;
    st->straddling_lanes += straddling;
    st->nodes_visited += visits;
    st->packets += packets;
}
