/*
 * make-atrium.c -- generate a Sponza-like atrium as a Wavefront OBJ/MTL pair.
 *
 * Why: the paper this toolkit follows renders the Sponza atrium, but that
 * model cannot be shipped with this project.  This program builds a stand-in
 * with the same kind of light transport: an open court lit from a sky
 * opening above, surrounded by two storeys of arcaded galleries that receive
 * mostly indirect light, bounced off the court floor and the arcades.
 *
 * Layout (units are metres, y is up, the floor is at y = 0, the model is
 * centred on the origin in x and z):
 *
 *   - The court is 30 m long (x) and 13 m wide (z), measured between the
 *     centre lines of the columns around it.  There are 10 bays of 3 m on
 *     each long side and 4 bays of 3.25 m on each short side.
 *   - Behind the columns are galleries 3 m deep on all four sides, closed by
 *     outer walls 0.5 m thick (outer faces at x = +-18.5 and z = +-10).
 *   - Ground storey: columns (box base, lathed shaft, box capital) carrying a
 *     wall pierced by semicircular arches, up to a floor slab at 7.0-7.5 m
 *     whose edge overhangs the arcade towards the court as a cornice.
 *   - Upper storey: the same on a smaller scale, with a balustrade (plinth,
 *     turned balusters, rail) between the columns, and a roof slab over the
 *     galleries at 14.5-15.0 m.  The outer walls also end at 15 m.
 *   - The court has no roof.  An emissive "sky" quad facing down covers the
 *     opening 0.1 m above the roof; a coping 0.3 m wide and 0.1 m high
 *     round the opening closes the gap between roof and sky, so the model
 *     is a closed enclosure and every ray ends on some surface.
 *   - Red drapes hang behind every other arch of the ground storey on the
 *     two long sides.
 *
 * Conventions of the output:
 *   - Every face is wound counter-clockwise seen from outside its solid
 *     (right-hand rule normal points out).  Faces that lie completely against
 *     another solid (a column base on the floor, an arcade wall under a slab,
 *     the joint between two wall panels, ...) are not emitted, so that no two
 *     faces ever coincide.  Such solids are therefore closed only together
 *     with the solid they rest on.  The only interpenetration is the upper
 *     balustrade rail, whose ends are sunk a little into the columns.
 *   - No triangle has an area below 1e-8 m^2 (the program checks this).
 *   - The output depends on nothing but this source (and the C library's
 *     sin/cos): fixed "%.6f" formatting, no time stamps, no randomness, so
 *     every run produces the same bytes.
 *
 * The sky-lit, textured variant (textured.json) is written beside it from the
 * same geometry: atrium-sky.obj leaves out the emissive sky quad, so the court
 * is open to the scene's sky and sun, and gives every face texture
 * coordinates by projecting its vertices along the axis its normal is closest
 * to (TEX_SCALE metres per repeat); atrium-sky.mtl names two procedural
 * textures, stone.png (ashlar courses) and floor.png (a checker of flags),
 * written here with libpng.  atrium.obj and atrium.mtl stay as they were.
 *
 * Usage: make-atrium [-o DIR]    writes DIR/atrium.obj and DIR/atrium.mtl,
 *                                DIR/atrium-sky.obj, DIR/atrium-sky.mtl,
 *                                DIR/stone.png and DIR/floor.png
 *
 * Build: cc -std=c17 -O2 -Wall -Wextra -Wpedantic -o make-atrium make-atrium.c -lpng -lm
 */

#include <errno.h>
#include <math.h>
#include <png.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PROG "make-atrium"

static const double PI = 3.14159265358979323846;

/* ------------------------------------------------------------------------ */
/* Dimensions                                                               */
/* ------------------------------------------------------------------------ */

#define BAYS_X 10 /* bays along each long side of the court  */
#define BAYS_Z 4  /* bays along each short side of the court */

static const double COURT_HX = 15.0; /* half length of the court (x)      */
static const double COURT_HZ = 6.5;  /* half width of the court (z)       */
static const double GALLERY = 3.0;   /* column line to outer wall inside  */
static const double OUTER_T = 0.5;   /* outer wall thickness              */
static const double SKY_GAP = 0.1;   /* sky quad height above the roof    */
static const double COPING_W = 0.3;  /* width of the coping round the sky */

/* Tessellation. */
enum {
    ARCH_SEGS = 64,     /* segments of one semicircular arch        */
    SHAFT_SEGS = 32,    /* segments around a column shaft           */
    BALUSTER_SEGS = 10, /* segments around a baluster               */
    DRAPE_COLS = 30,    /* drape grid, across                       */
    DRAPE_ROWS = 4      /* drape grid, down                         */
};

/* One storey of the arcade. */
typedef struct {
    double y_floor;           /* top of the floor or slab it stands on     */
    double base_h, base_half; /* column base box: height, half width       */
    double cap_h, cap_half;   /* capital box: height, half width           */
    double shaft_r;           /* nominal shaft radius                      */
    double y_spring;          /* top of the capitals = springing of arches */
    double y_top;             /* top of the arcade wall = slab underside   */
    double slab_top;          /* top of the slab (or roof) above           */
    double wall_half;         /* half thickness of the arcade wall         */
    double pillar_half;       /* half width of wall between two openings   */
    double cornice;           /* slab overhang past the arcade wall        */
} storey;

static const storey GROUND = {.y_floor = 0.0,
                              .base_h = 0.4,
                              .base_half = 0.4,
                              .cap_h = 0.4,
                              .cap_half = 0.375,
                              .shaft_r = 0.28,
                              .y_spring = 5.0,
                              .y_top = 7.0,
                              .slab_top = 7.5,
                              .wall_half = 0.25,
                              .pillar_half = 0.3,
                              .cornice = 0.15};

static const storey UPPER = {.y_floor = 7.5,
                             .base_h = 0.3,
                             .base_half = 0.3,
                             .cap_h = 0.3,
                             .cap_half = 0.3,
                             .shaft_r = 0.22,
                             .y_spring = 11.9,
                             .y_top = 14.5,
                             .slab_top = 15.0,
                             .wall_half = 0.2,
                             .pillar_half = 0.25,
                             .cornice = 0.15};

/* Upper balustrade. */
static const double PLINTH_H = 0.15, PLINTH_HALF = 0.15;
static const double RAIL_H = 0.15, RAIL_HALF = 0.16;
static const double BALUSTRADE_H = 1.1;   /* plinth bottom to rail top     */
static const double BALUSTER_PITCH = 0.3; /* approximate spacing           */

/* Drapes in the ground storey. */
static const double DRAPE_BOTTOM = 2.6;  /* lower hem height              */
static const double DRAPE_OFFSET = 0.45; /* centre, from the column line  */
static const double DRAPE_MARGIN = 0.5;  /* gap to the column centres     */
static const double DRAPE_T = 0.02;      /* cloth thickness               */
static const double DRAPE_FOLDS = 5.0;   /* waves across one drape        */

/* Smallest triangle area allowed in the output (m^2). */
static const double MIN_AREA = 1e-8;

/* ------------------------------------------------------------------------ */
/* Small vector helpers                                                     */
/* ------------------------------------------------------------------------ */

typedef struct {
    double x, y, z;
} vec3;

static vec3 v3(double x, double y, double z)
{
    vec3 v = {x, y, z};
    return v;
}

static vec3 v_sub(vec3 a, vec3 b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }

static double v_dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

static vec3 v_cross(vec3 a, vec3 b) { return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x); }

/* ------------------------------------------------------------------------ */
/* Mesh store                                                               */
/* ------------------------------------------------------------------------ */

/* Groups, in output order, and the material each one uses. */
enum group {
    G_FLOOR,
    G_OUTER_WALLS,
    G_COLUMN_BASES,
    G_COLUMNS,
    G_CAPITALS,
    G_ARCADES,
    G_SLABS,
    G_BALUSTRADE,
    G_BALUSTERS,
    G_ROOF,
    G_DRAPES,
    G_SKY,
    G_COUNT
};

static const struct {
    const char *name, *material;
} GROUPS[G_COUNT] = {
    [G_FLOOR] = {"floor", "floor"},
    [G_OUTER_WALLS] = {"outer_walls", "stone"},
    [G_COLUMN_BASES] = {"column_bases", "stone"},
    [G_COLUMNS] = {"columns", "stone"},
    [G_CAPITALS] = {"capitals", "stone"},
    [G_ARCADES] = {"arcades", "stone"},
    [G_SLABS] = {"floor_slabs", "stone"},
    [G_BALUSTRADE] = {"balustrade", "stone"},
    [G_BALUSTERS] = {"balusters", "stone"},
    [G_ROOF] = {"roof", "stone"},
    [G_DRAPES] = {"drapes", "drape"},
    [G_SKY] = {"sky", "sky"},
};

typedef struct {
    size_t a, b, c;
    int group;
} triangle;

static struct {
    vec3 *v;
    size_t nv, cap_v;
    triangle *t;
    size_t nt, cap_t;
    int group; /* group of the triangles emitted next */
} mesh;

static void die_nomem(void)
{
    fprintf(stderr, PROG ": out of memory\n");
    exit(1);
}

static void *grow(void *p, size_t *cap, size_t elem)
{
    size_t n = *cap ? *cap * 2 : 1024;
    void *q = realloc(p, n * elem);
    if (!q)
        die_nomem();
    *cap = n;
    return q;
}

static void set_group(int g) { mesh.group = g; }

static size_t add_vertex(vec3 p)
{
    if (mesh.nv == mesh.cap_v)
        mesh.v = grow(mesh.v, &mesh.cap_v, sizeof *mesh.v);
    mesh.v[mesh.nv] = p;
    return mesh.nv++;
}

/*
 * Add triangle (a, b, c).  `out` is any vector on the outer side of the
 * surface; the winding is chosen so that the right-hand-rule normal points
 * the same way, which keeps every solid consistently oriented without having
 * to get the vertex order right by hand in each emitter.
 */
static void emit_tri(size_t a, size_t b, size_t c, vec3 out)
{
    vec3 n = v_cross(v_sub(mesh.v[b], mesh.v[a]), v_sub(mesh.v[c], mesh.v[a]));
    double area = 0.5 * sqrt(v_dot(n, n));

    if (area < MIN_AREA) {
        fprintf(stderr, PROG ": internal error: degenerate triangle (area %g)\n", area);
        exit(1);
    }
    if (v_dot(n, out) < 0.0) {
        size_t t = b;
        b = c;
        c = t;
    }
    if (mesh.nt == mesh.cap_t)
        mesh.t = grow(mesh.t, &mesh.cap_t, sizeof *mesh.t);
    mesh.t[mesh.nt++] = (triangle){a, b, c, mesh.group};
}

/* Quad a-b-c-d (in cyclic order around its boundary) as two triangles. */
static void emit_quad(size_t a, size_t b, size_t c, size_t d, vec3 out)
{
    emit_tri(a, b, c, out);
    emit_tri(a, c, d, out);
}

/* ------------------------------------------------------------------------ */
/* Axis-aligned boxes                                                       */
/* ------------------------------------------------------------------------ */

/* Face selection for emit_box(). */
enum { F_NX = 1, F_PX = 2, F_NY = 4, F_PY = 8, F_NZ = 16, F_PZ = 32, F_ALL = 63, F_NO_BOTTOM = F_ALL & ~F_NY };

/* Emit the selected faces of the box [lo, hi]. */
static void emit_box(vec3 lo, vec3 hi, unsigned faces)
{
    /* corner index: bit 0 = x high, bit 1 = y high, bit 2 = z high */
    static const struct {
        unsigned flag;
        int c[4];
        double nx, ny, nz;
    } FACE[6] = {
        {F_NX, {0, 4, 6, 2}, -1, 0, 0}, {F_PX, {1, 3, 7, 5}, 1, 0, 0},  {F_NY, {0, 1, 5, 4}, 0, -1, 0},
        {F_PY, {2, 6, 7, 3}, 0, 1, 0},  {F_NZ, {0, 2, 3, 1}, 0, 0, -1}, {F_PZ, {4, 5, 7, 6}, 0, 0, 1},
    };
    size_t idx[8];
    int have[8] = {0};

    for (int f = 0; f < 6; f++) {
        if (!(faces & FACE[f].flag))
            continue;
        for (int k = 0; k < 4; k++) {
            int c = FACE[f].c[k];
            if (!have[c]) {
                idx[c] = add_vertex(v3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z));
                have[c] = 1;
            }
        }
        emit_quad(idx[FACE[f].c[0]], idx[FACE[f].c[1]], idx[FACE[f].c[2]], idx[FACE[f].c[3]],
                  v3(FACE[f].nx, FACE[f].ny, FACE[f].nz));
    }
}

/* ------------------------------------------------------------------------ */
/* Run frames: one side of the court                                        */
/* ------------------------------------------------------------------------ */

/*
 * A frame describes one side of the court.  Coordinates in a frame are
 * (u, y, w): u runs along the side, w across it, measured from the column
 * centre line.  `out` is the sign of w that points away from the court.
 */
typedef struct {
    int along_x; /* nonzero: u is x and w is z; zero: u is z, w is x */
    double line; /* z (or x) of the column centre line               */
    double out;  /* +1 or -1                                         */
} frame;

static vec3 frame_point(const frame *f, double u, double y, double w)
{
    return f->along_x ? v3(u, y, f->line + w) : v3(f->line + w, y, u);
}

static vec3 frame_dir(const frame *f, double du, double dy, double dw)
{
    return f->along_x ? v3(du, dy, dw) : v3(dw, dy, du);
}

/* Face selection for emit_frame_box(), in frame terms. */
enum { FU0 = 1, FU1 = 2, FY0 = 4, FY1 = 8, FW0 = 16, FW1 = 32 };

/* A box given in frame coordinates (u0 < u1, y0 < y1, w0 < w1). */
static void emit_frame_box(const frame *f, double u0, double u1, double y0, double y1, double w0, double w1,
                           unsigned faces)
{
    unsigned world = 0;

    if (faces & FY0)
        world |= F_NY;
    if (faces & FY1)
        world |= F_PY;
    if (faces & FU0)
        world |= f->along_x ? F_NX : F_NZ;
    if (faces & FU1)
        world |= f->along_x ? F_PX : F_PZ;
    if (faces & FW0)
        world |= f->along_x ? F_NZ : F_NX;
    if (faces & FW1)
        world |= f->along_x ? F_PZ : F_PX;
    emit_box(frame_point(f, u0, y0, w0), frame_point(f, u1, y1, w1), world);
}

/* ------------------------------------------------------------------------ */
/* Surfaces of revolution                                                   */
/* ------------------------------------------------------------------------ */

/*
 * Lathe a profile around the vertical axis through (cx, cz).  profile[i] is
 * {height above y0, radius}, listed bottom to top.  Only the side surface is
 * made: the ends always rest against a base, capital, plinth or rail.
 */
static void emit_lathe(double cx, double y0, double cz, const double (*profile)[2], int npoints, int segs)
{
    size_t first = mesh.nv;

    for (int i = 0; i < npoints; i++)
        for (int k = 0; k < segs; k++) {
            double a = 2.0 * PI * k / segs;
            double r = profile[i][1];
            add_vertex(v3(cx + r * cos(a), y0 + profile[i][0], cz + r * sin(a)));
        }
    for (int i = 0; i + 1 < npoints; i++) {
        /* outward normal of the profile segment in the (radius, height) plane */
        double dy = profile[i + 1][0] - profile[i][0];
        double dr = profile[i + 1][1] - profile[i][1];
        for (int k = 0; k < segs; k++) {
            int k1 = (k + 1) % segs;
            double a = 2.0 * PI * (k + 0.5) / segs;
            vec3 out = v3(dy * cos(a), -dr, dy * sin(a));
            size_t lo = first + (size_t)i * segs, hi = lo + segs;
            emit_quad(lo + k, lo + k1, hi + k1, hi + k, out);
        }
    }
}

/* ------------------------------------------------------------------------ */
/* Building elements                                                        */
/* ------------------------------------------------------------------------ */

/* Column shaft: a slight taper (entasis), a torus-like foot, a neck ring. */
static void emit_shaft(double x, double z, const storey *s)
{
    double r = s->shaft_r;
    double y0 = s->y_floor + s->base_h;
    double h = s->y_spring - s->cap_h - y0;
    const double profile[][2] = {
        {0.0, 1.10 * r},
        {0.3 * r, 1.10 * r},
        {0.5 * r, r},
        {0.4 * h, r},
        {h - 0.6 * r, 0.88 * r},
        {h - 0.6 * r, 0.98 * r},
        {h - 0.3 * r, 0.98 * r},
        {h - 0.3 * r, 0.88 * r},
        {h, 0.88 * r},
    };
    emit_lathe(x, y0, z, profile, (int)(sizeof profile / sizeof profile[0]), SHAFT_SEGS);
}

static void emit_column_base(double x, double z, const storey *s)
{
    double b = s->base_half;
    emit_box(v3(x - b, s->y_floor, z - b), v3(x + b, s->y_floor + s->base_h, z + b), F_NO_BOTTOM);
}

static void emit_capital(double x, double z, const storey *s)
{
    double c = s->cap_half;
    emit_box(v3(x - c, s->y_spring - s->cap_h, z - c), v3(x + c, s->y_spring, z + c), F_ALL);
}

/*
 * One bay of an arcade wall: the panel u in [ua, ub], y in [ys, yt], both
 * faces of the wall (w = -half and +half), pierced by a semicircular opening
 * of radius r centred at (m, ys), plus the intrados (the curved underside of
 * the arch).  Each face is triangulated as a fan from its top-left corner
 * over the left quarter of the arch and from its top-right corner over the
 * right quarter; both corners see their whole quarter because the panel
 * is wider and taller than the opening.  The panel bottom rests on the
 * capitals and its top against the slab, so neither is emitted.
 */
static void emit_arch_bay(const frame *f, double ua, double ub, double m, double r, double ys, double yt, double half)
{
    size_t arc[2][ARCH_SEGS + 1];
    const int mid = ARCH_SEGS / 2;

    for (int side = 0; side < 2; side++) {
        double w = side ? half : -half;
        vec3 out = frame_dir(f, 0.0, 0.0, side ? 1.0 : -1.0);
        size_t tl, tm, tr;

        for (int j = 0; j <= ARCH_SEGS; j++) {
            double a = PI * (1.0 - (double)j / ARCH_SEGS);
            arc[side][j] = add_vertex(frame_point(f, m + r * cos(a), ys + r * sin(a), w));
        }
        tl = add_vertex(frame_point(f, ua, yt, w));
        tm = add_vertex(frame_point(f, m, yt, w));
        tr = add_vertex(frame_point(f, ub, yt, w));

        if (m - r - ua > 1e-9) {
            size_t bl = add_vertex(frame_point(f, ua, ys, w));
            emit_tri(bl, arc[side][0], tl, out);
        }
        for (int j = 0; j < mid; j++)
            emit_tri(tl, arc[side][j], arc[side][j + 1], out);
        emit_tri(tl, arc[side][mid], tm, out);
        emit_tri(tm, arc[side][mid], tr, out);
        for (int j = mid; j < ARCH_SEGS; j++)
            emit_tri(tr, arc[side][j], arc[side][j + 1], out);
        if (ub - (m + r) > 1e-9) {
            size_t br = add_vertex(frame_point(f, ub, ys, w));
            emit_tri(arc[side][ARCH_SEGS], br, tr, out);
        }
    }

    /* intrados: faces point towards the centre of the arch */
    for (int j = 0; j < ARCH_SEGS; j++) {
        double a = PI * (1.0 - (j + 0.5) / ARCH_SEGS);
        vec3 out = frame_dir(f, -cos(a), -sin(a), 0.0);
        emit_quad(arc[0][j], arc[0][j + 1], arc[1][j + 1], arc[1][j], out);
    }
}

/*
 * The arcade wall of one side and storey: one arch per bay between the
 * columns cols[0..ncols-1].  The wall runs from u_start to u_end, which may
 * reach past the end columns (to close a corner) or stop short of them (to
 * butt against the wall of the neighbouring side).  End faces are emitted
 * only if `ends` is set.
 */
static void emit_arcade_wall(const frame *f, const double *cols, int ncols, double u_start, double u_end, int ends,
                             const storey *s)
{
    double h = s->wall_half;

    for (int k = 0; k + 1 < ncols; k++) {
        double ua = k == 0 ? u_start : cols[k];
        double ub = k + 2 == ncols ? u_end : cols[k + 1];
        double m = 0.5 * (cols[k] + cols[k + 1]);
        double r = 0.5 * (cols[k + 1] - cols[k]) - s->pillar_half;
        emit_arch_bay(f, ua, ub, m, r, s->y_spring, s->y_top, h);
    }
    if (ends)
        emit_frame_box(f, u_start, u_end, s->y_spring, s->y_top, -h, h, FU0 | FU1);
}

/*
 * Upper-storey balustrade in the bay between columns c0 < c1: a plinth
 * between the column bases, turned balusters, and a rail whose ends are
 * sunk into the column shafts.
 */
static void emit_balustrade_bay(const frame *f, double c0, double c1, const storey *s)
{
    double y0 = s->y_floor;
    double y_rail = y0 + BALUSTRADE_H - RAIL_H;
    double b = s->base_half;
    /* rail end: inside the polygonal shaft, 1 cm deeper than its corners */
    double r_in = s->shaft_r * cos(PI / SHAFT_SEGS);
    double e = sqrt(r_in * r_in - RAIL_HALF * RAIL_HALF) - 0.01;
    double span = (c1 - c0) - 2.0 * b;
    int n = (int)floor(span / BALUSTER_PITCH);
    double hb = y_rail - (y0 + PLINTH_H);
    const double profile[][2] = {
        {0.0, 0.045}, {0.10 * hb, 0.062}, {0.33 * hb, 0.075}, {0.65 * hb, 0.032}, {0.86 * hb, 0.042}, {hb, 0.042},
    };

    set_group(G_BALUSTRADE);
    emit_frame_box(f, c0 + b, c1 - b, y0, y0 + PLINTH_H, -PLINTH_HALF, PLINTH_HALF, FY1 | FW0 | FW1);
    emit_frame_box(f, c0 + e, c1 - e, y_rail, y_rail + RAIL_H, -RAIL_HALF, RAIL_HALF, FY0 | FY1 | FW0 | FW1);

    set_group(G_BALUSTERS);
    for (int i = 0; i < n; i++) {
        double u = c0 + b + span * (i + 0.5) / n;
        vec3 p = frame_point(f, u, y0 + PLINTH_H, 0.0);
        emit_lathe(p.x, p.y, p.z, profile, (int)(sizeof profile / sizeof profile[0]), BALUSTER_SEGS);
    }
}

/*
 * A drape hanging from the underside of the slab (y_top) down to
 * DRAPE_BOTTOM, behind the arcade wall on the gallery side, between u0 and
 * u1.  It is a thin closed sheet whose folds deepen towards the hem.  The
 * top edge touches the slab and is not emitted.
 */
static void emit_drape(const frame *f, double u0, double u1, double y_top)
{
    size_t grid[2][DRAPE_ROWS + 1][DRAPE_COLS + 1];
    double wc = f->out * DRAPE_OFFSET;

    for (int side = 0; side < 2; side++) {
        double dw = (side ? 0.5 : -0.5) * DRAPE_T;
        for (int j = 0; j <= DRAPE_ROWS; j++) {
            double t = (double)j / DRAPE_ROWS; /* 0 at top, 1 at hem */
            double y = y_top - (y_top - DRAPE_BOTTOM) * t;
            double amp = 0.02 + 0.06 * t;
            for (int i = 0; i <= DRAPE_COLS; i++) {
                double s = (double)i / DRAPE_COLS;
                double w = wc + dw + amp * sin(2.0 * PI * DRAPE_FOLDS * s);
                grid[side][j][i] = add_vertex(frame_point(f, u0 + (u1 - u0) * s, y, w));
            }
        }
    }
    for (int side = 0; side < 2; side++) {
        vec3 out = frame_dir(f, 0.0, 0.0, side ? 1.0 : -1.0);
        for (int j = 0; j < DRAPE_ROWS; j++)
            for (int i = 0; i < DRAPE_COLS; i++)
                emit_quad(grid[side][j][i], grid[side][j][i + 1], grid[side][j + 1][i + 1], grid[side][j + 1][i], out);
    }
    for (int i = 0; i < DRAPE_COLS; i++) /* hem */
        emit_quad(grid[0][DRAPE_ROWS][i], grid[0][DRAPE_ROWS][i + 1], grid[1][DRAPE_ROWS][i + 1],
                  grid[1][DRAPE_ROWS][i], v3(0.0, -1.0, 0.0));
    for (int j = 0; j < DRAPE_ROWS; j++) { /* side edges */
        emit_quad(grid[0][j][0], grid[1][j][0], grid[1][j + 1][0], grid[0][j + 1][0], frame_dir(f, -1.0, 0.0, 0.0));
        emit_quad(grid[0][j][DRAPE_COLS], grid[1][j][DRAPE_COLS], grid[1][j + 1][DRAPE_COLS],
                  grid[0][j + 1][DRAPE_COLS], frame_dir(f, 1.0, 0.0, 0.0));
    }
}

/*
 * A horizontal slab spanning the galleries all around the court: from the
 * inside faces of the outer walls to an inner edge at (+-inner_hx,
 * +-inner_hz).  Built from two long pieces (full length in x) and two short
 * pieces between them; faces against the outer walls or against the other
 * pieces are not emitted.
 */
static void emit_gallery_slab(double y0, double y1, double inner_hx, double inner_hz)
{
    double ox = COURT_HX + GALLERY, oz = COURT_HZ + GALLERY;

    emit_box(v3(-ox, y0, -oz), v3(ox, y1, -inner_hz), F_NY | F_PY | F_PZ);
    emit_box(v3(-ox, y0, inner_hz), v3(ox, y1, oz), F_NY | F_PY | F_NZ);
    emit_box(v3(-ox, y0, -inner_hz), v3(-inner_hx, y1, inner_hz), F_NY | F_PY | F_PX);
    emit_box(v3(inner_hx, y0, -inner_hz), v3(ox, y1, inner_hz), F_NY | F_PY | F_NX);
}

/* ------------------------------------------------------------------------ */
/* The whole atrium                                                         */
/* ------------------------------------------------------------------------ */

static double col_x[BAYS_X + 1], col_z[BAYS_Z + 1];

/* The four sides of the court: south (z < 0), north, west (x < 0), east. */
static frame side_frame(int side)
{
    switch (side) {
    case 0: return (frame){1, -COURT_HZ, -1.0};
    case 1: return (frame){1, COURT_HZ, 1.0};
    case 2: return (frame){0, -COURT_HX, -1.0};
    default: return (frame){0, COURT_HX, 1.0};
    }
}

/* Column centres along a side; long sides include the corner columns. */
static const double *side_columns(int side, int *n)
{
    if (side < 2) {
        *n = BAYS_X + 1;
        return col_x;
    }
    *n = BAYS_Z + 1;
    return col_z;
}

/* Every column position once: all of the long sides, inner ones of the short. */
typedef void column_fn(double x, double z, const storey *s);

static void for_each_column(column_fn *fn, const storey *s)
{
    for (int side = 0; side < 2; side++)
        for (int k = 0; k <= BAYS_X; k++)
            fn(col_x[k], side ? COURT_HZ : -COURT_HZ, s);
    for (int side = 0; side < 2; side++)
        for (int k = 1; k < BAYS_Z; k++)
            fn(side ? COURT_HX : -COURT_HX, col_z[k], s);
}

static void build_storey(const storey *s)
{
    set_group(G_COLUMN_BASES);
    for_each_column(emit_column_base, s);
    set_group(G_COLUMNS);
    for_each_column(emit_shaft, s);
    set_group(G_CAPITALS);
    for_each_column(emit_capital, s);

    /*
     * Arcade walls.  The long sides run through the corners to the outer
     * faces of the short sides' walls; the short sides stop against them.
     */
    set_group(G_ARCADES);
    for (int side = 0; side < 4; side++) {
        frame f = side_frame(side);
        int n;
        const double *cols = side_columns(side, &n);
        double h = s->wall_half;
        if (side < 2)
            emit_arcade_wall(&f, cols, n, cols[0] - h, cols[n - 1] + h, 1, s);
        else
            emit_arcade_wall(&f, cols, n, cols[0] + h, cols[n - 1] - h, 0, s);
    }
}

static void build_atrium(void)
{
    double ox = COURT_HX + GALLERY, oz = COURT_HZ + GALLERY;
    double top = UPPER.slab_top;

    for (int k = 0; k <= BAYS_X; k++)
        col_x[k] = -COURT_HX + 2.0 * COURT_HX * k / BAYS_X;
    for (int k = 0; k <= BAYS_Z; k++)
        col_z[k] = -COURT_HZ + 2.0 * COURT_HZ * k / BAYS_Z;

    set_group(G_FLOOR);
    emit_box(v3(-ox - OUTER_T, 0.0, -oz - OUTER_T), v3(ox + OUTER_T, 0.0, oz + OUTER_T), F_PY);

    /* Outer walls: the long ones run the full length, the short ones between. */
    set_group(G_OUTER_WALLS);
    emit_box(v3(-ox - OUTER_T, 0.0, -oz - OUTER_T), v3(ox + OUTER_T, top, -oz), F_NO_BOTTOM);
    emit_box(v3(-ox - OUTER_T, 0.0, oz), v3(ox + OUTER_T, top, oz + OUTER_T), F_NO_BOTTOM);
    emit_box(v3(-ox - OUTER_T, 0.0, -oz), v3(-ox, top, oz), F_NX | F_PX | F_PY);
    emit_box(v3(ox, 0.0, -oz), v3(ox + OUTER_T, top, oz), F_NX | F_PX | F_PY);

    build_storey(&GROUND);
    build_storey(&UPPER);

    /* Floor slab between the storeys, roof over the upper galleries. */
    set_group(G_SLABS);
    emit_gallery_slab(GROUND.y_top, GROUND.slab_top, COURT_HX - GROUND.wall_half - GROUND.cornice,
                      COURT_HZ - GROUND.wall_half - GROUND.cornice);
    set_group(G_ROOF);
    emit_gallery_slab(UPPER.y_top, UPPER.slab_top, COURT_HX - UPPER.wall_half - UPPER.cornice,
                      COURT_HZ - UPPER.wall_half - UPPER.cornice);

    /* Balustrade in every bay of the upper storey. */
    for (int side = 0; side < 4; side++) {
        frame f = side_frame(side);
        int n;
        const double *cols = side_columns(side, &n);
        for (int k = 0; k + 1 < n; k++)
            emit_balustrade_bay(&f, cols[k], cols[k + 1], &UPPER);
    }

    /* Drapes behind every other ground-storey arch of the long sides. */
    set_group(G_DRAPES);
    for (int side = 0; side < 2; side++) {
        frame f = side_frame(side);
        for (int k = 1; k < BAYS_X; k += 2)
            emit_drape(&f, col_x[k] + DRAPE_MARGIN, col_x[k + 1] - DRAPE_MARGIN, GROUND.y_top);
    }

    /*
     * Sky: covers the court opening SKY_GAP above the roof, facing down.  A
     * low coping around the opening rises from the roof to the sky quad and
     * closes the slit between them, so no ray can leave the model.
     */
    {
        double hx = COURT_HX - UPPER.wall_half - UPPER.cornice;
        double hz = COURT_HZ - UPPER.wall_half - UPPER.cornice;
        double y = top + SKY_GAP;
        double c = COPING_W;

        set_group(G_ROOF);
        emit_box(v3(-hx - c, top, -hz - c), v3(hx + c, y, -hz), F_NO_BOTTOM);
        emit_box(v3(-hx - c, top, hz), v3(hx + c, y, hz + c), F_NO_BOTTOM);
        emit_box(v3(-hx - c, top, -hz), v3(-hx, y, hz), F_NX | F_PX | F_PY);
        emit_box(v3(hx, top, -hz), v3(hx + c, y, hz), F_NX | F_PX | F_PY);
        set_group(G_SKY);
        emit_box(v3(-hx, y, -hz), v3(hx, y, hz), F_NY);
    }
}

/* ------------------------------------------------------------------------ */
/* Output                                                                   */
/* ------------------------------------------------------------------------ */

/* A FILE with a sticky error: after the first failure, output is dropped. */
typedef struct {
    FILE *fp;
    int err; /* errno of the first failed write, or 0 */
} writer;

#if defined(__GNUC__)
__attribute__((format(printf, 2, 3)))
#endif
static void
out(writer *w, const char *fmt, ...);

static void out(writer *w, const char *fmt, ...)
{
    va_list ap;

    if (w->err)
        return;
    errno = 0;
    va_start(ap, fmt);
    if (vfprintf(w->fp, fmt, ap) < 0)
        w->err = errno ? errno : EIO;
    va_end(ap);
}

/* Coordinate with exactly six decimals and never "-0.000000". */
static double clean(double v) { return fabs(v) < 5e-7 ? 0.0 : v; }

static void write_mtl(writer *w)
{
    out(w, "# atrium.mtl -- materials for atrium.obj, written by " PROG "\n"
           "#\n"
           "# Kd diffuse reflectance, Ks specular reflectance (always 0 here),\n"
           "# Ke emitted radiance in W/(m^2 sr) (only the sky emits).\n"
           "\n"
           "newmtl floor\n"
           "Kd 0.55 0.5 0.45\n"
           "Ks 0 0 0\n"
           "\n"
           "newmtl stone\n"
           "Kd 0.7 0.65 0.55\n"
           "Ks 0 0 0\n"
           "\n"
           "newmtl drape\n"
           "Kd 0.6 0.1 0.1\n"
           "Ks 0 0 0\n"
           "\n"
           "newmtl sky\n"
           "Kd 0 0 0\n"
           "Ks 0 0 0\n"
           "Ke 2 2.4 3\n");
}

static void write_obj(writer *w)
{
    out(w,
        "# atrium.obj -- a Sponza-like atrium, written by " PROG "\n"
        "#\n"
        "# A stand-in for the Sponza atrium (which cannot be shipped): an open\n"
        "# court surrounded by two storeys of arcades, lit through a sky\n"
        "# opening.  Units: metres.  y is up, the floor is at y = 0.\n"
        "# Faces are wound counter-clockwise seen from outside.\n"
        "# %zu vertices, %zu triangles.\n"
        "\n"
        "mtllib atrium.mtl\n"
        "\n",
        mesh.nv, mesh.nt);
    for (size_t i = 0; i < mesh.nv; i++)
        out(w, "v %.6f %.6f %.6f\n", clean(mesh.v[i].x), clean(mesh.v[i].y), clean(mesh.v[i].z));
    for (int g = 0; g < G_COUNT; g++) {
        out(w, "\ng %s\nusemtl %s\n", GROUPS[g].name, GROUPS[g].material);
        for (size_t i = 0; i < mesh.nt; i++)
            if (mesh.t[i].group == g)
                out(w, "f %zu %zu %zu\n", mesh.t[i].a + 1, mesh.t[i].b + 1, mesh.t[i].c + 1);
    }
}

static void report(const char *what, const char *path, int err);

/* ------------------------------------------------------------------------ */
/* The sky-lit, textured variant                                            */
/* ------------------------------------------------------------------------ */

static const double TEX_SCALE = 2.0; /* metres covered by one repeat of a texture */
enum { TEX_SIZE = 256 };             /* pixels per side of each texture           */

/* Axis (0 x, 1 y, 2 z) the normal of triangle t is closest to. */
static int tri_axis(const triangle *t)
{
    vec3 n = v_cross(v_sub(mesh.v[t->b], mesh.v[t->a]), v_sub(mesh.v[t->c], mesh.v[t->a]));
    double ax = fabs(n.x), ay = fabs(n.y), az = fabs(n.z);
    return ay >= ax && ay >= az ? 1 : ax >= az ? 0 : 2;
}

static void write_sky_mtl(writer *w)
{
    out(w, "# atrium-sky.mtl -- materials for atrium-sky.obj, written by " PROG "\n"
           "#\n"
           "# Kd diffuse reflectance, scaled by the map_Kd texture (its texels are\n"
           "# at most 1); nothing emits: the scene's sky and sun light the court.\n"
           "\n"
           "newmtl floor\n"
           "Kd 0.55 0.5 0.45\n"
           "Ks 0 0 0\n"
           "map_Kd floor.png\n"
           "\n"
           "newmtl stone\n"
           "Kd 0.7 0.65 0.55\n"
           "Ks 0 0 0\n"
           "map_Kd stone.png\n"
           "\n"
           "newmtl drape\n"
           "Kd 0.6 0.1 0.1\n"
           "Ks 0 0 0\n");
}

/*
 * Every vertex gets three texture coordinates, its projections along x, y
 * and z (vt 3 i + 1, 3 i + 2, 3 i + 3 for vertex i + 1); a face uses the one
 * of the axis its normal is closest to, so walls, floors and ceilings all
 * see the texture undistorted at TEX_SCALE metres per repeat.
 */
static void write_sky_obj(writer *w)
{
    size_t nt = 0;
    for (size_t i = 0; i < mesh.nt; i++)
        nt += mesh.t[i].group != G_SKY;
    out(w,
        "# atrium-sky.obj -- the atrium open to the sky, textured, written by " PROG "\n"
        "#\n"
        "# atrium.obj without its emissive sky quad, with texture coordinates.\n"
        "# Units: metres.  y is up, the floor is at y = 0.\n"
        "# %zu vertices, %zu triangles.\n"
        "\n"
        "mtllib atrium-sky.mtl\n"
        "\n",
        mesh.nv, nt);
    for (size_t i = 0; i < mesh.nv; i++)
        out(w, "v %.6f %.6f %.6f\n", clean(mesh.v[i].x), clean(mesh.v[i].y), clean(mesh.v[i].z));
    for (size_t i = 0; i < mesh.nv; i++) {
        vec3 p = mesh.v[i];
        out(w, "vt %.6f %.6f\nvt %.6f %.6f\nvt %.6f %.6f\n", clean(p.z / TEX_SCALE), clean(p.y / TEX_SCALE),
            clean(p.x / TEX_SCALE), clean(p.z / TEX_SCALE), clean(p.x / TEX_SCALE), clean(p.y / TEX_SCALE));
    }
    for (int g = 0; g < G_COUNT; g++) {
        if (g == G_SKY)
            continue;
        out(w, "\ng %s\nusemtl %s\n", GROUPS[g].name, GROUPS[g].material);
        for (size_t i = 0; i < mesh.nt; i++)
            if (mesh.t[i].group == g) {
                const triangle *t = &mesh.t[i];
                size_t k = (size_t)tri_axis(t) + 1;
                out(w, "f %zu/%zu %zu/%zu %zu/%zu\n", t->a + 1, 3 * t->a + k, t->b + 1, 3 * t->b + k, t->c + 1,
                    3 * t->c + k);
            }
    }
}

/* A hash of (a, b, c) in [0, 1): the variation of a block or a pixel. */
static double hash01(uint32_t a, uint32_t b, uint32_t c)
{
    uint32_t h = a * 0x9e3779b1u ^ (b + 0x7f4a7c15u) * 0x85ebca77u ^ (c + 0x165667b1u) * 0xc2b2ae3du;
    h ^= h >> 15;
    h *= 0x2c1b3c6du;
    h ^= h >> 12;
    h *= 0x297a2d39u;
    h ^= h >> 15;
    return (h >> 8) / 16777216.0;
}

/* Linear reflectance scale in [0, 1] to an 8-bit sRGB code (the loader decodes sRGB). */
static unsigned char srgb8(double v)
{
    v = v < 0.0 ? 0.0 : v > 1.0 ? 1.0 : v;
    double e = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
    return (unsigned char)lround(255.0 * e);
}

/*
 * stone.png: ashlar, 4 courses of 0.5 m per repeat, blocks 1 m long, every
 * other course shifted by half a block; mortar joints 3 px; each block a
 * little lighter or darker and warmer or cooler, with a fine grain.
 * floor.png: square flags of 0.5 m in two tones, joints 2 px, a fine grain.
 * Both repeat seamlessly.  Values are scales of the material's Kd.
 */
static void texel(int floor, int x, int y, double rgb[3])
{
    double grain = 0.06 * (hash01((uint32_t)x, (uint32_t)y, floor ? 7u : 3u) - 0.5);
    if (floor) {
        int tx = x / 64, ty = y / 64, jx = x % 64, jy = y % 64;
        int joint = jx < 2 || jy < 2;
        double tone = (tx + ty) % 2 ? 0.95 : 0.62;
        tone += 0.08 * (hash01((uint32_t)tx, (uint32_t)ty, 11u) - 0.5);
        double v = joint ? 0.35 : tone + grain;
        rgb[0] = v, rgb[1] = v * 0.97, rgb[2] = v * 0.93;
        return;
    }
    int course = y / 64, shift = course % 2 ? 64 : 0;
    int bx = ((x + shift) % TEX_SIZE) / 128, jx = (x + shift) % 128, jy = y % 64;
    int joint = jx < 3 || jy < 3;
    double h1 = hash01((uint32_t)bx, (uint32_t)course, 5u), h2 = hash01((uint32_t)bx, (uint32_t)course, 9u);
    double v = joint ? 0.45 : 0.86 + 0.14 * (h1 - 0.5) + grain;
    double warm = 0.06 * (h2 - 0.5);
    rgb[0] = v * (1.0 + warm), rgb[1] = v, rgb[2] = v * (1.0 - warm);
}

/* Writes texture `floor` (0 stone, 1 floor) as an 8-bit RGB PNG; 0 on success. */
static int write_png(const char *path, int floor)
{
    static unsigned char rows[TEX_SIZE][3 * TEX_SIZE];
    for (int y = 0; y < TEX_SIZE; y++)
        for (int x = 0; x < TEX_SIZE; x++) {
            double c[3];
            texel(floor, x, y, c);
            for (int k = 0; k < 3; k++)
                rows[y][3 * x + k] = srgb8(c[k]);
        }
    errno = 0;
    FILE *fp = fopen(path, "wb");
    if (!fp) {
        report("cannot create", path, errno ? errno : EIO);
        return -1;
    }
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!png || !info || setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        fclose(fp);
        report("cannot write", path, EIO);
        remove(path);
        return -1;
    }
    png_init_io(png, fp);
    png_set_IHDR(png, info, TEX_SIZE, TEX_SIZE, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
                 PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int y = 0; y < TEX_SIZE; y++)
        png_write_row(png, rows[y]);
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    if (fclose(fp) != 0) {
        report("cannot write", path, errno ? errno : EIO);
        remove(path);
        return -1;
    }
    return 0;
}

static void report(const char *what, const char *path, int err)
{
    fprintf(stderr, PROG ": %s '%s': %s\n", what, path, strerror(err));
}

/* Write a file with `fn`; on failure report, remove it and return -1. */
static int write_file(const char *path, void (*fn)(writer *))
{
    writer w = {NULL, 0};

    errno = 0;
    w.fp = fopen(path, "wb");
    if (!w.fp) {
        report("cannot create", path, errno ? errno : EIO);
        return -1;
    }
    fn(&w);
    if (!w.err && fflush(w.fp) != 0)
        w.err = errno ? errno : EIO;
    if (fclose(w.fp) != 0 && !w.err)
        w.err = errno ? errno : EIO;
    if (w.err) {
        report("cannot write", path, w.err);
        remove(path);
        return -1;
    }
    return 0;
}

/* dir + "/" + name, without doubling a trailing slash. */
static char *join(const char *dir, const char *name)
{
    size_t n = strlen(dir);
    int slash = n > 0 && dir[n - 1] != '/';
    char *p = malloc(n + (size_t)slash + strlen(name) + 1);

    if (!p)
        die_nomem();
    sprintf(p, "%s%s%s", dir, slash ? "/" : "", name);
    return p;
}

static void usage(FILE *fp)
{
    fprintf(fp, "usage: " PROG " [-o DIR]\n"
                "Generate a Sponza-like atrium (units: metres, y up) and write it as\n"
                "DIR/atrium.obj and DIR/atrium.mtl (DIR defaults to \".\"), and its sky-lit,\n"
                "textured variant as DIR/atrium-sky.obj, atrium-sky.mtl, stone.png and floor.png.\n"
                "\n"
                "  -o DIR   write the files into DIR, which must exist\n"
                "  --help   show this help and exit\n");
}

int main(int argc, char **argv)
{
    const char *dir = ".";
    char *obj, *mtl, *obj_tmp, *mtl_tmp;

    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(argv[i], "-o") == 0) {
            if (i + 1 >= argc || argv[i + 1][0] == '\0') {
                fprintf(stderr, PROG ": option '-o' needs a directory\n");
                usage(stderr);
                return 2;
            }
            dir = argv[++i];
        } else {
            fprintf(stderr, PROG ": %s '%s'\n", argv[i][0] == '-' ? "unknown option" : "unexpected argument", argv[i]);
            usage(stderr);
            return 2;
        }
    }

    build_atrium();

    obj = join(dir, "atrium.obj");
    mtl = join(dir, "atrium.mtl");
    obj_tmp = join(dir, ".atrium.obj.tmp");
    mtl_tmp = join(dir, ".atrium.mtl.tmp");

    if (write_file(mtl_tmp, write_mtl) != 0)
        return 1;
    if (write_file(obj_tmp, write_obj) != 0) {
        remove(mtl_tmp);
        return 1;
    }
    errno = 0;
    if (rename(mtl_tmp, mtl) != 0) {
        report("cannot rename to", mtl, errno ? errno : EIO);
        remove(mtl_tmp);
        remove(obj_tmp);
        return 1;
    }
    errno = 0;
    if (rename(obj_tmp, obj) != 0) {
        report("cannot rename to", obj, errno ? errno : EIO);
        remove(obj_tmp);
        return 1;
    }
    fprintf(stderr, PROG ": wrote %zu triangles to '%s'\n", mesh.nt, obj);

    /* The sky-lit, textured variant: each file to a temporary name, then renamed. */
    {
        static const char *const names[4] = {"atrium-sky.mtl", "atrium-sky.obj", "stone.png", "floor.png"};
        for (int i = 0; i < 4; i++) {
            char tmpname[64];
            snprintf(tmpname, sizeof tmpname, ".%s.tmp", names[i]);
            char *dst = join(dir, names[i]), *tmp = join(dir, tmpname);
            int bad = i == 0   ? write_file(tmp, write_sky_mtl)
                      : i == 1 ? write_file(tmp, write_sky_obj)
                               : write_png(tmp, i == 3);
            errno = 0;
            if (!bad && rename(tmp, dst) != 0) {
                report("cannot rename to", dst, errno ? errno : EIO);
                remove(tmp);
                bad = 1;
            }
            free(dst);
            free(tmp);
            if (bad)
                return 1;
        }
    }

    free(obj);
    free(mtl);
    free(obj_tmp);
    free(mtl_tmp);
    free(mesh.v);
    free(mesh.t);
    return 0;
}
