/*
 * cgcontact from C: build a lattice body, deform it, locate points and measure gaps to its
 * surface, list the cells a node moved too far inverts, print and check the answers.
 *
 * The points are made from known (cell, xi): the deformed point at xi of a chosen cell, computed
 * here with the trilinear map, so the program checks the library against an answer it constructed
 * itself. It exits with status 1 on any wrong answer, 0 when all are right.
 *
 * Build (CI does this in .ci/run, after `cargo build --release -p cgcontact-capi`):
 *   cc -std=c99 -Wall -Wextra -O2 locate.c -I ../../include -L $TARGET/release \
 *      -lcgcontact_capi -Wl,-rpath,$TARGET/release -lm -o locate
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "cgcontact.h"

enum { NX = 4, NY = 3, NZ = 2 };
static const double ORIGIN[3] = {1.0, -2.0, 0.5};
static const double H[3] = {0.5, 0.25, 0.4};

/* VTK hexahedron corners as lattice offsets. */
static const int CORNER[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                 {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

/* A smooth displacement, well under a cell. */
static void displacement(const double x[3], double u[3]) {
    u[0] = 0.05 * sin(3.0 * x[1]);
    u[1] = 0.03 * x[0] * x[2];
    u[2] = -0.1 * (x[0] - 1.0) * (x[2] - 0.5);
}

/* The deformed point at xi of cell (i, j, k): the trilinear map of its deformed corners. */
static void deformed_point(int i, int j, int k, const double xi[3], double p[3]) {
    p[0] = p[1] = p[2] = 0.0;
    for (int c = 0; c < 8; c++) {
        double x[3], u[3], w = 1.0;
        int ijk[3] = {i + CORNER[c][0], j + CORNER[c][1], k + CORNER[c][2]};
        for (int a = 0; a < 3; a++) {
            x[a] = ORIGIN[a] + H[a] * ijk[a];
            w *= CORNER[c][a] ? 0.5 * (1.0 + xi[a]) : 0.5 * (1.0 - xi[a]);
        }
        displacement(x, u);
        for (int a = 0; a < 3; a++) p[a] += w * (x[a] + u[a]);
    }
}

static int check(cgc_error code, const char *what) {
    if (code != CGC_ERROR_OK) {
        fprintf(stderr, "%s failed (code %d): %s\n", what, (int)code, cgc_last_error());
        return 0;
    }
    return 1;
}

int main(void) {
    printf("cgcontact %s, C ABI %u\n", cgc_version(), cgc_abi_version());
    if (cgc_abi_version() != CGC_ABI_VERSION) {
        fprintf(stderr, "header and library disagree on the ABI version\n");
        return 1;
    }

    /* The body: every cell of a 4 x 3 x 2 lattice, deformed by `displacement` at its nodes. */
    const uint32_t counts[3] = {NX, NY, NZ};
    cgc_body *body = NULL;
    if (!check(cgc_body_from_lattice(ORIGIN, H, counts, NULL, 0, &body), "cgc_body_from_lattice"))
        return 1;
    size_t n_nodes = 0;
    cgc_body_node_count(body, &n_nodes);
    double *u = malloc(3 * n_nodes * sizeof *u);
    for (size_t n = 0; n < n_nodes; n++) { /* node i + (NX+1)(j + (NY+1) k), x y z per node */
        size_t ijk[3] = {n % (NX + 1), (n / (NX + 1)) % (NY + 1), n / ((NX + 1) * (NY + 1))};
        double x[3];
        for (int a = 0; a < 3; a++) x[a] = ORIGIN[a] + H[a] * (double)ijk[a];
        displacement(x, &u[3 * n]);
    }
    if (!check(cgc_body_set_displacements(body, u, n_nodes, CGC_LAYOUT_NODE_MAJOR),
               "cgc_body_set_displacements"))
        return 1;

    cgc_settings settings;
    cgc_settings_init(CGC_PRECISION_F64, &settings);
    settings.threads = 1;
    cgc_locator *locator = NULL;
    if (!check(cgc_locator_new(body, &settings, &locator), "cgc_locator_new")) return 1;

    /* Points from known (cell, xi), one per cell, and one far outside. */
    enum { KNOWN = NX * NY * NZ, N = KNOWN + 1 };
    double points[3 * N], known_xi[3 * N], xi[3 * N];
    int64_t known_cell[N], cells[N];
    uint8_t status[N];
    for (int c = 0; c < KNOWN; c++) {
        int i = c % NX, j = (c / NX) % NY, k = c / (NX * NY);
        double *x = &known_xi[3 * c];
        x[0] = 0.9 * sin(0.7 * c);
        x[1] = 0.8 * cos(1.3 * c);
        x[2] = 0.95 * sin(0.4 * c + 0.3);
        deformed_point(i, j, k, x, &points[3 * c]);
        known_cell[c] = c; /* cell i + NX (j + NY k) */
    }
    points[3 * KNOWN] = points[3 * KNOWN + 1] = points[3 * KNOWN + 2] = 100.0;
    known_cell[KNOWN] = -1;

    if (!check(cgc_locate(locator, points, N, cells, xi, status), "cgc_locate")) return 1;

    int wrong = 0;
    double worst = 0.0;
    printf("point  cell  xi                              status\n");
    for (int p = 0; p < N; p++) {
        printf("%5d  %4lld  % .12f % .12f % .12f  %d\n", p, (long long)cells[p], xi[3 * p],
               xi[3 * p + 1], xi[3 * p + 2], status[p]);
        if (cells[p] != known_cell[p]) {
            fprintf(stderr, "point %d: cell %lld, expected %lld\n", p, (long long)cells[p],
                    (long long)known_cell[p]);
            wrong++;
        } else if (known_cell[p] >= 0) {
            for (int a = 0; a < 3; a++) {
                double e = fabs(xi[3 * p + a] - known_xi[3 * p + a]);
                worst = e > worst ? e : worst;
            }
        } else if (status[p] != CGC_POINT_OUTSIDE || !isnan(xi[3 * p])) {
            fprintf(stderr, "point %d: expected outside with NaN xi\n", p);
            wrong++;
        }
    }
    if (worst > 1e-12) {
        fprintf(stderr, "largest xi error %.3e exceeds 1e-12\n", worst);
        wrong++;
    }

    /* The next solver iteration, warm started: cells and xi hold the answers just found and are
     * overwritten. A point still in its cell costs one Newton inversion from its previous xi. Here
     * the displacements did not change, so the same known cells and xi must come back. */
    if (!check(cgc_relocate(locator, points, N, cells, xi, status), "cgc_relocate")) return 1;
    for (int p = 0; p < N; p++) {
        int off = cells[p] != known_cell[p];
        for (int a = 0; known_cell[p] >= 0 && a < 3; a++)
            off |= fabs(xi[3 * p + a] - known_xi[3 * p + a]) > 1e-12;
        if (off) {
            fprintf(stderr, "warm start, point %d: cell %lld, expected %lld\n", p,
                    (long long)cells[p], (long long)known_cell[p]);
            wrong++;
        }
    }
    printf("warm start: %d points relocated from their previous answers\n", N);

    /* Gaps: the centre c of the top face of cell (1, 1, NZ - 1) lies on the deformed surface (gap
     * 0, face 5 of that cell); the point c + 0.05 n, n the normal found there, is 0.05 above it
     * with c still its closest point. Up to 0.2 away is searched. */
    {
        const double top[3] = {0.0, 0.0, 1.0};
        double at[6], gap[2], closest[6], normal[6];
        int64_t face_cell[2];
        int32_t face[2];
        deformed_point(1, 1, NZ - 1, top, at);
        if (!check(cgc_gap(locator, at, 1, 0.2, gap, closest, normal, face_cell, face), "cgc_gap"))
            return 1;
        for (int a = 0; a < 3; a++) at[3 + a] = at[a] + 0.05 * normal[a];
        if (!check(cgc_gap(locator, at, 2, 0.2, gap, closest, normal, face_cell, face), "cgc_gap"))
            return 1;
        const int64_t cell = 1 + NX * (1 + NY * (NZ - 1));
        for (int p = 0; p < 2; p++)
            printf("gap of (% .6f, % .6f, % .6f): % .12f, face %d of cell %lld, normal (% .6f, % .6f, % .6f)\n",
                   at[3 * p], at[3 * p + 1], at[3 * p + 2], gap[p], (int)face[p],
                   (long long)face_cell[p], normal[3 * p], normal[3 * p + 1], normal[3 * p + 2]);
        double off = 0.0;
        for (int a = 0; a < 3; a++) off += fabs(closest[3 + a] - at[a]);
        if (fabs(gap[0]) > 1e-12 || fabs(gap[1] - 0.05) > 1e-9 || off > 1e-9 || face[0] != 5 ||
            face[1] != 5 || face_cell[0] != cell || face_cell[1] != cell) {
            fprintf(stderr, "wrong gaps at the top face of cell %lld\n", (long long)cell);
            wrong++;
        }
        /* Farther than the search distance: NaN and -1. A negative distance is an error. */
        at[5] += 1.0;
        cgc_gap(locator, at, 2, 0.2, gap, closest, normal, face_cell, face);
        if (!isnan(gap[1]) || face_cell[1] != -1 || face[1] != -1) wrong++;
        cgc_error bad = cgc_gap(locator, at, 2, -1.0, gap, NULL, NULL, NULL, NULL);
        printf("a negative distance: code %d, \"%s\"\n", (int)bad, cgc_last_error());
        if (bad != CGC_ERROR_INVALID_ARGUMENT) wrong++;
    }

    /* Inverted cells: none under the smooth displacement. Node (2, 1, 1) moved 1.5 cells in x,
     * through its neighbour (3, 1, 1), turns the four cells (2, j, k) inside out. Updates do not
     * check for them (a pass over every cell): ask when wanted, the count first, then the cells. */
    size_t n_inverted = 1;
    if (!check(cgc_body_inverted_cells(body, NULL, 0, &n_inverted), "cgc_body_inverted_cells") ||
        n_inverted != 0)
        wrong++;
    double *moved = &u[3 * (2 + (NX + 1) * (1 + (NY + 1) * 1))];
    moved[0] += 1.5 * H[0];
    if (!check(cgc_body_set_displacements(body, u, n_nodes, CGC_LAYOUT_NODE_MAJOR),
               "cgc_body_set_displacements") ||
        !check(cgc_body_inverted_cells(body, NULL, 0, &n_inverted), "cgc_body_inverted_cells"))
        return 1;
    int64_t *inverted = malloc((n_inverted ? n_inverted : 1) * sizeof *inverted);
    if (!check(cgc_body_inverted_cells(body, inverted, n_inverted, &n_inverted),
               "cgc_body_inverted_cells"))
        return 1;
    const int64_t expected[4] = {2, 2 + NX, 2 + NX * NY, 2 + NX * (1 + NY)}; /* cells (2, j, k) */
    printf("node (2, 1, 1) moved through (3, 1, 1): %zu inverted cells:", n_inverted);
    for (size_t c = 0; c < n_inverted; c++) {
        printf(" %lld", (long long)inverted[c]);
        if (n_inverted != 4 || inverted[c] != expected[c]) wrong++;
    }
    printf("\n");
    if (n_inverted != 4) wrong++;
    free(inverted);
    moved[0] -= 1.5 * H[0];
    if (!check(cgc_body_set_displacements(body, u, n_nodes, CGC_LAYOUT_NODE_MAJOR),
               "cgc_body_set_displacements"))
        return 1;

    /* Errors are codes with a message, never crashes. */
    points[1] = NAN;
    cgc_error code = cgc_locate(locator, points, N, cells, xi, status);
    printf("a NaN point: code %d, \"%s\"\n", (int)code, cgc_last_error());
    if (code != CGC_ERROR_NON_FINITE_POINT || status[0] != CGC_POINT_NON_FINITE || cells[1] != 1) {
        fprintf(stderr, "a NaN point was not reported as such\n");
        wrong++;
    }
    code = cgc_body_set_displacements(body, u, n_nodes - 1, CGC_LAYOUT_NODE_MAJOR);
    printf("a short displacement array: code %d, \"%s\"\n", (int)code, cgc_last_error());
    if (code != CGC_ERROR_LENGTH_MISMATCH) wrong++;
    code = cgc_locate(NULL, points, N, cells, xi, status);
    if (code != CGC_ERROR_NULL_POINTER) wrong++;

    cgc_locator_free(locator);
    cgc_body_free(body);
    free(u);
    printf("%d points, largest xi error %.2e, %s\n", N, worst, wrong ? "WRONG" : "all right");
    return wrong ? 1 : 0;
}
