/* gslib findpts on the binaries of `export_block` (benches/examples/export_block.rs).
 *
 * Usage: findpts_bench DIR [REPEATS [HASH_PER_ELEMENT]]
 *
 * Reads DIR/{meta.txt,nodes.f64,elements.u32,points.f64,cells.u32,xi.f64}, sets up gslib's
 * findpts on the linear hexes (nr = ns = nt = 2), times the setup, then times findpts over all
 * points (one process, one thread, serial gslib: no MPI), best of REPEATS (default 3) calls, and
 * checks gslib's element and r against the known cell and xi. See docs/gslib.md.
 *
 * Built against a serial gslib (make MPI=0 ... install): gslib.h includes the config.h that
 * gslib's install writes to build/include/gslib (prefix gslib_, no GSLIB_USE_MPI), so
 * benches/gslib/run.sh puts that directory first on the include path. */

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "gslib.h"

/* findpts parameters (docs/gslib.md explains them). */
#define BBOX_TOL 0.01 /* bounding boxes grown by 1% of their size */
#define NPT_MAX 128   /* points per batch of the element-level Newton */
#define NEWT_TOL 1e-13 /* Newton stops when |dr|_1 < tol */
#define AGREE_TOL 1e-10

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void *read_file(const char *dir, const char *name, size_t expected) {
  char path[4096];
  FILE *f;
  void *p;
  long size;
  snprintf(path, sizeof path, "%s/%s", dir, name);
  f = fopen(path, "rb");
  if (!f) { fprintf(stderr, "cannot open %s\n", path); exit(1); }
  fseek(f, 0, SEEK_END);
  size = ftell(f);
  fseek(f, 0, SEEK_SET);
  if ((size_t)size != expected) {
    fprintf(stderr, "%s: %ld bytes, expected %zu\n", path, size, expected);
    exit(1);
  }
  p = malloc(expected ? expected : 1);
  if (!p) { fprintf(stderr, "out of memory reading %s\n", path); exit(1); }
  if (expected && fread(p, 1, expected, f) != expected) {
    fprintf(stderr, "short read on %s\n", path);
    exit(1);
  }
  fclose(f);
  return p;
}

static unsigned long meta_value(const char *dir, const char *key) {
  char path[4096], line[512];
  size_t n = strlen(key);
  FILE *f;
  snprintf(path, sizeof path, "%s/meta.txt", dir);
  f = fopen(path, "r");
  if (!f) { fprintf(stderr, "cannot open %s\n", path); exit(1); }
  while (fgets(line, sizeof line, f))
    if (!strncmp(line, key, n) && line[n] == ' ') {
      fclose(f);
      return strtoul(line + n + 1, NULL, 10);
    }
  fprintf(stderr, "%s: no %s\n", path, key);
  exit(1);
}

static double peak_rss_mib(void) {
  struct rusage u;
  getrusage(RUSAGE_SELF, &u);
  return (double)u.ru_maxrss / 1024.0; /* Linux: KiB */
}

int main(int argc, char **argv) {
  const char *dir;
  int repeats = 3, rep;
  unsigned long hash_per_element = 8;
  uint hash_size;
  unsigned long nel, npt, i;
  double *nodes, *pts, *xi;
  uint32_t *elements, *cells;
  uint *code, *proc, *el;
  double *r, *dist2;
  const double *elx[3];
  const double *x_base[3];
  const unsigned x_stride[3] = {3 * sizeof(double), 3 * sizeof(double), 3 * sizeof(double)};
  const unsigned n[3] = {2, 2, 2}, m[3] = {4, 4, 4};
  struct comm comm;
  struct findpts_data_3 *fd;
  double t0, setup_s, find_s = INFINITY, rss_before_setup;
  unsigned long agree = 0, code0 = 0, code1 = 0, code2 = 0, wrong_cell = 0;
  double max_dxi = 0;

  if (argc < 2) { fprintf(stderr, "usage: %s DIR [REPEATS]\n", argv[0]); return 2; }
  dir = argv[1];
  if (argc > 2) repeats = atoi(argv[2]);
  if (repeats < 1) repeats = 1;
  if (argc > 3) hash_per_element = strtoul(argv[3], NULL, 10);
  if (hash_per_element < 1) hash_per_element = 1;

  nel = meta_value(dir, "elements");
  npt = meta_value(dir, "points");
  if (meta_value(dir, "nodes_per_element") != 8) { fprintf(stderr, "not linear hexes\n"); return 1; }
  nodes = read_file(dir, "nodes.f64", nel * 8 * 3 * sizeof(double));
  elements = read_file(dir, "elements.u32", nel * sizeof(uint32_t));
  pts = read_file(dir, "points.f64", npt * 3 * sizeof(double));
  cells = read_file(dir, "cells.u32", npt * sizeof(uint32_t));
  xi = read_file(dir, "xi.f64", npt * 3 * sizeof(double));
  elx[0] = nodes, elx[1] = nodes + nel * 8, elx[2] = nodes + 2 * nel * 8;
  code = malloc(npt * sizeof(uint));
  proc = malloc(npt * sizeof(uint));
  el = malloc(npt * sizeof(uint));
  r = malloc(npt * 3 * sizeof(double));
  dist2 = malloc(npt * sizeof(double));
  if (!code || !proc || !el || !r || !dist2) { fprintf(stderr, "out of memory\n"); return 1; }
  x_base[0] = pts, x_base[1] = pts + 1, x_base[2] = pts + 2;
  rss_before_setup = peak_rss_mib();

  comm_init(&comm, 0);
  t0 = now();
  /* Local and global hash table sizes: HASH_PER_ELEMENT × elements (default 8 = nr*ns*nt, as
   * Nek5000 and gslib's tests pass: the number of mesh nodes). The size bounds the whole table
   * (cell offsets and element lists): at 1 × elements nothing is left for cells and every point
   * tests every element's bounding box. */
  hash_size = (uint)(hash_per_element * nel);
  fd = findpts_setup_3(&comm, elx, n, (uint)nel, m, BBOX_TOL, hash_size, hash_size, NPT_MAX,
                       NEWT_TOL);
  setup_s = now() - t0;

  for (rep = 0; rep < repeats; ++rep) {
    double s;
    t0 = now();
    findpts_3(code, sizeof(uint), proc, sizeof(uint), el, sizeof(uint), r, 3 * sizeof(double),
              dist2, sizeof(double), x_base, x_stride, (uint)npt, fd);
    s = now() - t0;
    if (s < find_s) find_s = s;
  }

  for (i = 0; i < npt; ++i) {
    if (code[i] == 0) ++code0;
    else if (code[i] == 1) ++code1;
    else ++code2;
    if (code[i] != 2) {
      double d = 0;
      int k;
      if (elements[el[i]] != cells[i]) { ++wrong_cell; continue; }
      for (k = 0; k < 3; ++k) d = fmax(d, fabs(r[3 * i + k] - xi[3 * i + k]));
      if (d > max_dxi) max_dxi = d;
      if (d <= AGREE_TOL) ++agree;
    }
  }

  printf("gslib cells=%lu points=%lu setup_s=%.4f find_s=%.4f points_per_s=%.0f "
         "repeats=%d hash_size=%lu peak_rss_mib=%.1f rss_before_setup_mib=%.1f\n",
         nel, npt, setup_s, find_s, (double)npt / find_s, repeats, (unsigned long)hash_size,
         peak_rss_mib(),
         rss_before_setup);
  printf("gslib agree_1e-10=%lu code0=%lu code1_border=%lu code2_notfound=%lu "
         "wrong_cell=%lu max_dr_in_known_cell=%.3g\n",
         agree, code0, code1, code2, wrong_cell, max_dxi);

  findpts_free_3(fd);
  comm_free(&comm);
  return 0;
}
