/* photonmap.c: the photon map format, written by build-photonmap and read by
 * simd-gather. Record i is KD-tree node i and the photon on its split plane. The
 * reader checks the tree's shape: every node reached exactly once from the root,
 * child indices in range, each split within the low mantissa bits of its photon. */
#include <inttypes.h>
#include <stdlib.h>

#include "formats.h"

static const pm_channel_t map_channels[] = {
    {"node", PM_TYPE_U32, 2, PM_CH_REQUIRED, "1",
     "KD-tree node: split (f32 bits, axis in the low 2) and right child index"},
    {"position", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_FINITE, "m", "photon position (hot data)"},
    {"power", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_NONNEG, "W", "RGB flux (cold data)"},
    {"normal", PM_TYPE_F32, 3, PM_CH_REQUIRED | PM_CH_UNIT, "1", "unit surface normal"},
    {"direction", PM_TYPE_F32, 3, PM_CH_UNIT, "1", "unit direction back toward the photon's source (glossy scenes)"},
    {"width", PM_TYPE_F32, 1, PM_CH_POSITIVE, "m", "kernel width h(x_i) (variable-width estimator)"},
};

static pm_result_t validate_tree(const pm_table_t *t, const char *path)
{
    uint64_t n = t->count;
    if (n == 0)
        return PM_OK;
    if (n > UINT32_MAX - 1)
        return pm_error_set(PM_ERR_INPUT, "photon map '%s' has %" PRIu64 " nodes, more than 32-bit indices reach",
                            path, n);
    const pm_kdnode_t *node = t->col[PM_MAP_NODE];
    const float *pos = t->col[PM_MAP_POSITION];
    unsigned char *seen = calloc(n, 1);
    uint32_t *stack = malloc((n + 2) * sizeof *stack); /* +2: the cycle check runs after a push */
    pm_result_t res = PM_OK;
    if (!seen || !stack) {
        res = pm_error_set(PM_ERR_NOMEM, "out of memory checking photon map '%s'", path);
        goto done;
    }
    uint64_t top = 0, reached = 0;
    stack[top++] = 0;
    while (top && res == PM_OK) {
        uint32_t i = stack[--top];
        if (seen[i]) {
            res = pm_error_set(PM_ERR_INPUT, "corrupt photon map '%s': node %" PRIu32 " is reached twice", path, i);
            break;
        }
        seen[i] = 1;
        reached++;
        uint32_t axis = pm_kdnode_axis(node[i]), child = node[i].child;
        if (axis == PM_KD_LEAF) {
            if (child != PM_KD_NONE)
                res = pm_error_set(PM_ERR_INPUT, "corrupt photon map '%s': leaf %" PRIu32 " has child %" PRIu32,
                                   path, i, child);
            continue;
        }
        uint32_t sb, pb;
        memcpy(&sb, &node[i].split, 4);
        memcpy(&pb, &pos[3 * (size_t)i + axis], 4);
        if ((sb & ~3u) != (pb & ~3u)) {
            res = pm_error_set(PM_ERR_INPUT,
                               "corrupt photon map '%s': node %" PRIu32 " splits %c at %.9g but its photon is at %.9g",
                               path, i, "xyz"[axis], node[i].split, pos[3 * (size_t)i + axis]);
            break;
        }
        int has_left = child != (uint64_t)i + 1, has_right = child != PM_KD_NONE;
        if (has_left && (uint64_t)i + 1 >= n) {
            res = pm_error_set(PM_ERR_INPUT, "corrupt photon map '%s': node %" PRIu32 " has its left child past the end",
                               path, i);
            break;
        }
        if (has_right && (child <= i || child >= n)) {
            res = pm_error_set(PM_ERR_INPUT,
                               "corrupt photon map '%s': node %" PRIu32 " has right child %" PRIu32 " outside (%" PRIu32
                               ", %" PRIu64 ")",
                               path, i, child, i, n);
            break;
        }
        if (has_right)
            stack[top++] = child;
        if (has_left)
            stack[top++] = i + 1;
        if (top > n) { /* more pushes than nodes: some node is reached twice */
            res = pm_error_set(PM_ERR_INPUT, "corrupt photon map '%s': the tree has a cycle", path);
            break;
        }
    }
    if (res == PM_OK && reached != n)
        res = pm_error_set(PM_ERR_INPUT, "corrupt photon map '%s': %" PRIu64 " of %" PRIu64 " nodes unreachable from the root",
                           path, n - reached, n);
done:
    free(seen);
    free(stack);
    return res;
}

const pm_schema_t pm_photonmap_schema = {
    .name = "photonmap",
    .major = 1,
    .minor = 0,
    .title = "photon map",
    .channels = map_channels,
    .nchannels = sizeof map_channels / sizeof map_channels[0],
    .validate_table = validate_tree,
};
