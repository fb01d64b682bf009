/*
 * make-caustic.c -- generate the caustic test scene as a Wavefront OBJ/MTL pair.
 *
 * Why: photon mapping's classic case is light reaching a diffuse surface through specular
 * bounces. This is the scene that shows it: a box open at the front, 2 m a side, with a white
 * floor, ceiling and back wall, a red wall on the camera's left and a green one on its right,
 * a square area light under the ceiling, and on the floor a glass sphere (index 1.5) that
 * focuses the light into a caustic under and beside it, and a mirror sphere (reflectance 0.95)
 * that throws the lamp's image over the room.
 *
 * Layout (metres, y up, floor at y = 0, the box centred on x = 0, z = 0; the camera looks
 * along +z from z = -3.6, so +x is on its left):
 *   - floor y = 0, ceiling y = 2, back wall z = 1, red wall x = 1 (left), green wall x = -1
 *     (right); the front (z = -1) is open;
 *   - the lamp: a 0.5 m square at y = 1.98 centred over the box, facing down;
 *   - the glass sphere: radius 0.35 m at (0.4, 0.35, -0.25), front left, resting on the floor;
 *   - the mirror sphere: radius 0.35 m at (-0.45, 0.35, 0.35), back right, resting on the floor.
 * The spheres are UV spheres of 128 longitudes and 64 latitude bands (pmtk shades with
 * geometric normals, so their facets show in the caustic at close range).
 *
 * Conventions of the output: every face is wound so that its right-hand-rule normal points
 * into the room (walls) or out of the solid (spheres, and the lamp downwards, the side it
 * emits from). Output depends on nothing but this source and the C library's sin and cos: fixed
 * "%.6f" formatting, no time stamps, so every run writes the same bytes.
 *
 * Usage: make-caustic [-o DIR]    writes DIR/caustic.obj and DIR/caustic.mtl
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NLON 128
#define NLAT 64

static unsigned nverts;

static void vertex(FILE *f, double x, double y, double z)
{
    fprintf(f, "v %.6f %.6f %.6f\n", x, y, z);
    nverts++;
}

/* A quad from four corners in order; its normal follows the right-hand rule. */
static void quad(FILE *f, const char *group, const char *mat, const double c[4][3])
{
    fprintf(f, "g %s\nusemtl %s\n", group, mat);
    for (int i = 0; i < 4; i++)
        vertex(f, c[i][0], c[i][1], c[i][2]);
    fprintf(f, "f %u %u %u %u\n", nverts - 3, nverts - 2, nverts - 1, nverts);
}

/* A UV sphere of radius r at (cx, cy, cz), faces wound outward. */
static void sphere(FILE *f, const char *group, const char *mat, double cx, double cy, double cz, double r)
{
    const double pi = 3.14159265358979323846;
    fprintf(f, "g %s\nusemtl %s\n", group, mat);
    unsigned base = nverts + 1; /* the north pole; ring j (1..NLAT-1) point k at base + 1 + (j-1) NLON + k */
    vertex(f, cx, cy + r, cz);
    for (int j = 1; j < NLAT; j++) {
        double t = pi * j / NLAT;
        for (int k = 0; k < NLON; k++) {
            double p = 2.0 * pi * k / NLON;
            vertex(f, cx + r * sin(t) * cos(p), cy + r * cos(t), cz + r * sin(t) * sin(p));
        }
    }
    unsigned south = nverts + 1;
    vertex(f, cx, cy - r, cz);
#define RING(j, k) (base + 1 + (unsigned)((j)-1) * NLON + (unsigned)((k) % NLON))
    for (int k = 0; k < NLON; k++)
        fprintf(f, "f %u %u %u\n", base, RING(1, k + 1), RING(1, k));
    for (int j = 1; j < NLAT - 1; j++)
        for (int k = 0; k < NLON; k++)
            fprintf(f, "f %u %u %u %u\n", RING(j, k), RING(j, k + 1), RING(j + 1, k + 1), RING(j + 1, k));
    for (int k = 0; k < NLON; k++)
        fprintf(f, "f %u %u %u\n", south, RING(NLAT - 1, k), RING(NLAT - 1, k + 1));
#undef RING
}

int main(int argc, char **argv)
{
    const char *dir = ".";
    if (argc == 3 && strcmp(argv[1], "-o") == 0)
        dir = argv[2];
    else if (argc != 1) {
        fprintf(stderr, "usage: make-caustic [-o DIR]\n");
        return 2;
    }
    char path[4096];
    snprintf(path, sizeof path, "%s/caustic.mtl", dir);
    FILE *m = fopen(path, "w");
    if (!m) {
        fprintf(stderr, "make-caustic: cannot create '%s': %s\n", path, strerror(errno));
        return 1;
    }
    fputs("# the caustic test scene (make-caustic.c)\n"
          "newmtl white\nKd 0.75 0.75 0.75\n\n"
          "newmtl red\nKd 0.63 0.065 0.05\n\n"
          "newmtl green\nKd 0.14 0.45 0.091\n\n"
          "newmtl lamp\nKd 0 0 0\nKe 15 15 15\n\n"
          "newmtl glass\nKd 0 0 0\nNi 1.5\nTf 1 1 1\nillum 7\n\n"
          "newmtl mirror\nKd 0 0 0\nKs 0.95 0.95 0.95\nillum 3\n",
          m);
    if (fclose(m) != 0) {
        fprintf(stderr, "make-caustic: cannot write '%s': %s\n", path, strerror(errno));
        return 1;
    }
    snprintf(path, sizeof path, "%s/caustic.obj", dir);
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "make-caustic: cannot create '%s': %s\n", path, strerror(errno));
        return 1;
    }
    fputs("# the caustic test scene (make-caustic.c)\nmtllib caustic.mtl\n", f);
    const double floor_[4][3] = {{-1, 0, -1}, {-1, 0, 1}, {1, 0, 1}, {1, 0, -1}};
    const double ceiling[4][3] = {{-1, 2, -1}, {1, 2, -1}, {1, 2, 1}, {-1, 2, 1}};
    const double back[4][3] = {{-1, 0, 1}, {-1, 2, 1}, {1, 2, 1}, {1, 0, 1}};
    const double left[4][3] = {{1, 0, -1}, {1, 0, 1}, {1, 2, 1}, {1, 2, -1}};
    const double right[4][3] = {{-1, 0, -1}, {-1, 2, -1}, {-1, 2, 1}, {-1, 0, 1}};
    const double lamp[4][3] = {{-0.25, 1.98, -0.25}, {0.25, 1.98, -0.25}, {0.25, 1.98, 0.25}, {-0.25, 1.98, 0.25}};
    quad(f, "floor", "white", floor_);
    quad(f, "ceiling", "white", ceiling);
    quad(f, "back", "white", back);
    quad(f, "left", "red", left);
    quad(f, "right", "green", right);
    quad(f, "lamp", "lamp", lamp);
    sphere(f, "glass_sphere", "glass", 0.4, 0.35, -0.25, 0.35);
    sphere(f, "mirror_sphere", "mirror", -0.45, 0.35, 0.35, 0.35);
    if (fclose(f) != 0) {
        fprintf(stderr, "make-caustic: cannot write '%s': %s\n", path, strerror(errno));
        return 1;
    }
    return 0;
}
