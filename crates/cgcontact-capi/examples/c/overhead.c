/*
 * What the C ABI adds to the library's query: cgc_locate (answers converted into the caller's
 * cell and xi arrays) against cgc_locator_query_seconds (the Rust library's locate_all_into into
 * its own warm answer buffer), on the same locator and points, interleaved, shortest of 15 runs.
 * The body is the Octave benchmark's: a 50 x 50 x 50 block, h = 0.2, a smooth displacement of up
 * to 0.4 h, and 1,000,000 random points inside it. A measurement, not a test.
 *
 *   cargo build --release -p cgcontact-capi
 *   cc -O2 overhead.c -I ../../include -L $TARGET/release -lcgcontact_capi \
 *      -Wl,-rpath,$TARGET/release -lm -o overhead && ./overhead
 */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "cgcontact.h"

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(void) {
    enum { NC = 50 };
    const double origin[3] = {0, 0, 0}, h[3] = {0.2, 0.2, 0.2};
    const uint32_t counts[3] = {NC, NC, NC};
    cgc_body *body;
    cgc_locator *locator;
    size_t m;
    if (cgc_body_from_lattice(origin, h, counts, NULL, 0, &body) != CGC_ERROR_OK) return 1;
    cgc_body_node_count(body, &m);
    double *u = malloc(3 * m * sizeof *u);
    for (size_t i = 0; i < m; i++) {
        double x = 0.2 * (double)(i % (NC + 1)), y = 0.2 * (double)((i / (NC + 1)) % (NC + 1)),
               z = 0.2 * (double)(i / ((NC + 1) * (NC + 1)));
        u[3 * i] = 0.08 * sin(0.7 * y);
        u[3 * i + 1] = 0.08 * cos(0.5 * x) * sin(0.4 * z);
        u[3 * i + 2] = -0.08 * sin(0.6 * x);
    }
    if (cgc_body_set_displacements(body, u, m, CGC_LAYOUT_NODE_MAJOR) != CGC_ERROR_OK) return 1;
    if (cgc_locator_new(body, NULL, &locator) != CGC_ERROR_OK) return 1;
    const size_t n = 1000000;
    double *points = malloc(3 * n * sizeof *points), *xi = malloc(3 * n * sizeof *xi);
    int64_t *cells = malloc(n * sizeof *cells);
    srand(1);
    for (size_t i = 0; i < 3 * n; i++) points[i] = 0.2 + 9.6 * rand() / (double)RAND_MAX;
    double api = INFINITY, library = INFINITY;
    for (int run = 0; run < 15; run++) {
        double t = now(), s;
        cgc_locate(locator, points, n, cells, xi, NULL);
        t = now() - t;
        api = t < api ? t : api;
        cgc_locator_query_seconds(locator, points, n, 1, &s);
        library = s < library ? s : library;
    }
    printf("1e6 points: cgc_locate %.2f ms, library locate_all_into %.2f ms: %+.1f %%\n", 1e3 * api,
           1e3 * library, 100 * (api / library - 1));
    cgc_locator_free(locator);
    cgc_body_free(body);
    free(u);
    free(points);
    free(xi);
    free(cells);
    return 0;
}
