/* scene_cache.h: a loaded scene kept in one file (docs/formats.md, "The scene cache"), so that
 * the programs of a render, and its reruns, read in milliseconds what the scene's import made
 * in tenths of a second (the sky-lit atrium's 6.8 MB OBJ: 0.18 s to import, 0.33 s with its
 * trial in a child; 6 ms from the cache).
 *
 * The file holds the scene as this build of pmtk loaded it and names what that load read:
 * the scene file's path as given (and the working directory when it is relative), every file
 * read with the XXH3-64 of its bytes (or that it was absent), the import limits, and the build
 * (a hash of the library's sources and flags, since the payload is the build's own structs).
 * It is used only when all of these are as they were: any edit to the scene file, a mesh, an
 * .mtl, a texture or the sky's map, another build or other limits make it a miss, and the
 * scene is loaded from its files again. A scene whose import reads files the loader cannot
 * name (glTF, Collada, FBX: assimp opens their buffers and images itself) is never cached. */
#ifndef PM_SCENE_CACHE_H
#define PM_SCENE_CACHE_H

#include <stddef.h>

#include "base/error.h"
#include "render/scene.h"

/* What a load through a cache did. */
typedef struct {
    int hit;        /* 1: the scene came from the cache */
    int written;    /* 1: the load was a miss and wrote the cache */
    char why[1400]; /* on a miss, why ("absent", "made from another build", "'x.obj' changed", ...);
                     * and when the write failed, why that failed */
} pm_scene_cache_status_t;

/* A cache is named by a file, or by a directory (one that exists, or a name ending in '/',
 * made when needed) holding a file per scene, scene-HASH.cache, HASH the XXH3-64 of the scene's
 * absolute path: PMTK_SCENE_CACHE=~/.cache/pmtk/ serves every scene a user renders. */

/* Writes s (loaded by pm_scene_load) to the cache, atomically and without fsync (a reader
 * checks its checksum first). PM_ERR_USAGE when s is uncacheable (its message says why); I/O
 * errors name the path. */
pm_result_t pm_scene_cache_write(const pm_scene_t *s, const char *cache);

/* The scene scene_path (named as pm_scene_load is given it) from the cache into *out,
 * when the cache holds it as above: PM_OK with st->hit 1. Otherwise PM_OK with st->hit 0, *out
 * zeroed and st->why saying why: a cache that is absent, damaged or another scene's is a miss,
 * never an error. Errors: out of memory. */
pm_result_t pm_scene_cache_read(const char *cache, const char *scene_path, pm_scene_t *out,
                                pm_scene_cache_status_t *st);

/* pm_scene_load through the cache at cache (NULL or "": none, and no file hashed): a hit, or
 * the scene loaded from its files and, with write_now and when it is cacheable, written to
 * cache (a failed write is no error: st says it). Without write_now a miss writes nothing: a
 * driver writes the scene it loaded (pm_scene_cache_write) once OUTDIR's lock is its own. st may
 * be NULL. pm_scene_load itself goes through the cache named by the environment's
 * PMTK_SCENE_CACHE, which pm-render sets to OUTDIR/scene.cache for its stages. */
pm_result_t pm_scene_load_cached(const char *scene_path, const char *cache, int write_now, pm_scene_t *out,
                                 pm_scene_cache_status_t *st);

#endif
