/* photonmap.c: the photon map format, written by build-photonmap and read by
 * simd-gather. Record i is KD-tree node i and the photon on its split plane. The
 * reader checks the whole tree in O(n): nodes in depth-first order (each left subtree
 * exactly [i+1, child)), child indices in range, each split within the low mantissa
 * bits of its photon, and every photon inside the planes of its ancestors (left of a
 * plane: coordinate <= the node photon's; right: >=), so a map it accepts is searched
 * correctly. */
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>

#include "formats/formats.h"

static const pm_channel_t map_channels[] = {
    {"node", PM_TYPE_U32, 2, PM_CH_REQUIRED, "1",
     "KD-tree node: split (f32 bits, axis in the low 2) and right child index"},
    {"position", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_FINITE, "m", "photon position (hot data)"},
    {"power", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_NONNEG, "W", "RGB flux (cold data)"},
    {"normal", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_UNIT, "1", "unit surface normal"},
    {"direction", PM_TYPE_F32, 3, PM_CH_UNIT, "1", "unit direction back toward the photon's source (glossy scenes)"},
    {"width", PM_TYPE_F32, 1, PM_CH_POSITIVE, "m", "kernel width h(x_i) (variable-width estimator)"},
};

/* One pending subtree of the check: its root and the box its photons must lie in, the
 * planes of its ancestors (their photons' coordinates, inclusive on both sides). */
typedef struct {
    uint32_t node, depth;
    float lo[3], hi[3];
} pending_t;

static pm_result_t validate_tree(const pm_table_t *t, const char *path)
{
    uint64_t n = t->count;
    if (n == 0)
        return PM_OK;
    if (n > UINT32_MAX - 1)
        return pm_error_set(PM_ERR_INPUT, "photon map '%s' has %" PRIu64 " nodes, more than 32-bit indices reach", path,
                            n);
    const pm_kdnode_t *node = t->col[PM_MAP_NODE];
    const float *pos = t->col[PM_MAP_POSITION];
    /* Pre-order: at node i the stack holds at most i entries, so n + 1 always suffice. */
    pending_t *stack = malloc((n + 1) * sizeof *stack);
    if (!stack)
        return pm_error_set(PM_ERR_NOMEM, "out of memory checking photon map '%s'", path);
    pm_result_t res = PM_OK;
    uint64_t top = 0, expected = 0;
    stack[top++] = (pending_t){0, 1, {-INFINITY, -INFINITY, -INFINITY}, {INFINITY, INFINITY, INFINITY}};
    while (top) {
        pending_t e = stack[--top];
        uint32_t i = e.node;
        /* Pre-order: the left subtree is exactly [i + 1, child) and the right starts at child. */
        if (i != expected) {
            res = pm_error_set(PM_ERR_INPUT,
                               "corrupt photon map '%s': node %" PRIu32
                               " is out of depth-first order (expected node %" PRIu64 " next)",
                               path, i, expected);
            break;
        }
        expected++;
        if (e.depth > PM_KD_MAX_DEPTH) {
            res = pm_error_set(PM_ERR_INPUT,
                               "photon map '%s' is deeper than %u levels at node %" PRIu32
                               " (searches keep a stack of that depth)",
                               path, PM_KD_MAX_DEPTH, i);
            break;
        }
        const float *p = &pos[3 * (size_t)i];
        int axis_out = -1;
        for (int k = 0; k < 3; k++)
            if (p[k] < e.lo[k] || p[k] > e.hi[k])
                axis_out = k;
        if (axis_out >= 0) {
            res = pm_error_set(PM_ERR_INPUT,
                               "corrupt photon map '%s': photon %" PRIu32 " at %c = %.9g lies outside "
                               "[%.9g, %.9g], the planes of its ancestors",
                               path, i, "xyz"[axis_out], p[axis_out], e.lo[axis_out], e.hi[axis_out]);
            break;
        }
        uint32_t axis = pm_kdnode_axis(node[i]), child = node[i].child;
        if (axis == PM_KD_LEAF) {
            if (child != PM_KD_NONE) {
                res = pm_error_set(PM_ERR_INPUT, "corrupt photon map '%s': leaf %" PRIu32 " has child %" PRIu32, path,
                                   i, child);
                break;
            }
            continue;
        }
        uint32_t sb, pb;
        memcpy(&sb, &node[i].split, 4);
        memcpy(&pb, &p[axis], 4);
        if ((sb & ~3u) != (pb & ~3u)) {
            res = pm_error_set(PM_ERR_INPUT,
                               "corrupt photon map '%s': node %" PRIu32 " splits %c at %.9g but its photon is at %.9g",
                               path, i, "xyz"[axis], node[i].split, p[axis]);
            break;
        }
        int has_left = child != (uint64_t)i + 1, has_right = child != PM_KD_NONE;
        if (has_left && (uint64_t)i + 1 >= n) {
            res = pm_error_set(PM_ERR_INPUT,
                               "corrupt photon map '%s': node %" PRIu32 " has its left child past the end", path, i);
            break;
        }
        if (has_right && (child <= i || child >= n)) {
            res = pm_error_set(PM_ERR_INPUT,
                               "corrupt photon map '%s': node %" PRIu32 " has right child %" PRIu32 " outside (%" PRIu32
                               ", %" PRIu64 ")",
                               path, i, child, i, n);
            break;
        }
        if (has_right) { /* pushed first, popped after the whole left subtree */
            pending_t r = e;
            r.node = child;
            r.depth = e.depth + 1;
            r.lo[axis] = p[axis];
            stack[top++] = r;
        }
        if (has_left) {
            pending_t l = e;
            l.node = i + 1;
            l.depth = e.depth + 1;
            l.hi[axis] = p[axis];
            stack[top++] = l;
        }
    }
    if (res == PM_OK && expected != n)
        res = pm_error_set(PM_ERR_INPUT,
                           "corrupt photon map '%s': %" PRIu64 " of %" PRIu64 " nodes unreachable from the root", path,
                           n - expected, n);
    free(stack);
    return res;
}

const pm_schema_t pm_photonmap_schema = {
    .name = "photonmap",
    .major = 2,
    .minor = 0,
    .oldest_major = 1,
    .title = "photon map",
    .channels = map_channels,
    .nchannels = sizeof map_channels / sizeof map_channels[0],
    .validate_table = validate_tree,
};
