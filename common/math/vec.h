/* vec.h: 3-vectors of floats, by value, for scalar code paths (SIMD code uses its own). */
#ifndef PM_VEC_H
#define PM_VEC_H

#include <math.h>

typedef struct {
    float x, y, z;
} pm_vec3_t;

static inline pm_vec3_t pm_v3(float x, float y, float z) { return (pm_vec3_t){x, y, z}; }
static inline pm_vec3_t pm_v3_load(const float *p) { return (pm_vec3_t){p[0], p[1], p[2]}; }
static inline void pm_v3_store(float *p, pm_vec3_t a) { p[0] = a.x, p[1] = a.y, p[2] = a.z; }
static inline pm_vec3_t pm_v3_add(pm_vec3_t a, pm_vec3_t b) { return pm_v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline pm_vec3_t pm_v3_sub(pm_vec3_t a, pm_vec3_t b) { return pm_v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline pm_vec3_t pm_v3_scale(pm_vec3_t a, float s) { return pm_v3(a.x * s, a.y * s, a.z * s); }
static inline float pm_v3_dot(pm_vec3_t a, pm_vec3_t b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline pm_vec3_t pm_v3_cross(pm_vec3_t a, pm_vec3_t b)
{
    return pm_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline float pm_v3_length(pm_vec3_t a) { return sqrtf(pm_v3_dot(a, a)); }
/* Unit vector along a; a zero vector stays zero rather than becoming NaN. */
static inline pm_vec3_t pm_v3_normalize(pm_vec3_t a)
{
    float len = pm_v3_length(a);
    return len > 0.0f ? pm_v3_scale(a, 1.0f / len) : a;
}

/* The dot product of two float[3] arrays, for code that keeps points and directions as
 * arrays (ray buffers, file records) rather than pm_vec3_t. */
static inline float pm_dot3(const float a[3], const float b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

#endif
