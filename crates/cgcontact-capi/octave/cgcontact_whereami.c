/*
 * cgcontact_whereami: the seed's `whereami` call for Octave and MATLAB, on cgcontact's C ABI.
 *
 *   [E, PosL] = cgcontact_whereami(XYZ, XYZ_N0, Topology, U)
 *   [E, PosL] = cgcontact_whereami(XYZ, XYZ_N0, Topology, U, Options)
 *   [E, PosL, Inverted] = cgcontact_whereami(XYZ, XYZ_N0, Topology, U [, Options])
 *
 *     XYZ       3 x n   points
 *     XYZ_N0    3 x m   undeformed nodes (on a lattice)
 *     Topology  8 x e   1-based node numbers per element, VTK hexahedron corner order
 *     U         m x 3   nodal displacements ([] or omitted: undeformed)
 *     E         1 x n   1-based element holding each point, 0 when none
 *     PosL      3 x n   local coordinates in [-1, 1]^3 (NaN when none)
 *     Inverted  1 x k   1-based elements that U inverts (see 'inverted_cells'), ascending; only
 *                       computed when asked for
 *     Options   struct ([] for none), any of: precision ('f64' or 'f32'), tol (Newton step), max_iter, threads,
 *               fill_hanging (true: hanging nodes take their constraint's value, U's is ignored);
 *               any other field is an error (a misspelt option would be ignored otherwise)
 *
 * Adaptive meshes work as uniform ones: elements of several sizes, each a dyadic refinement of
 * one lattice (edges h/2^l), with the hanging nodes (nodes of finer elements on an edge or a face
 * of a coarser neighbour) among XYZ_N0. A hanging node's displacement must be the trilinear
 * interpolation of the coarse element it hangs on (1/2 and 1/2 of an edge's ends, 1/4 each of a
 * face's corners, recursively): otherwise the error cgcontact:hangingConstraint names how many
 * break it and the worst node, unless Options.fill_hanging is true.
 *
 * Handles, for solver loops (build once, update displacements, locate):
 *
 *   H = cgcontact_whereami('new', XYZ_N0, Topology [, Options])
 *   cgcontact_whereami('update', H, U)                        % U m x 3 ([] is an error)
 *   [E, PosL] = cgcontact_whereami('locate', H, XYZ)
 *   [E, PosL] = cgcontact_whereami('relocate', H, XYZ, E0, PosL0)  % warm start, see below
 *   [G, C, N, FE, F] = cgcontact_whereami('gap', H, XYZ, D)    % gaps to the surface, within D
 *   Inverted = cgcontact_whereami('inverted_cells', H)         % elements U inverts, 1 x k
 *   Unresolved = cgcontact_whereami('unresolved_cells', H)     % elements f64 cannot resolve
 *   S = cgcontact_whereami('query_seconds', H, XYZ, Repeats)   % the library's own query time
 *   cgcontact_whereami('free', H)                               % optional
 *   N = cgcontact_whereami('handles')                           % how many are live
 *
 * 'gap' measures each point's signed gap to the body's deformed boundary surface (the faces no
 * other element covers), searched within D >= 0 (finite):
 *     G   1 x n   the distance to the closest surface point, negative inside the body
 *     C   3 x n   that closest point
 *     N   3 x n   the unit outward normal there: XYZ = C + G .* N
 *     FE  1 x n   1-based element whose face holds C (0 when none)
 *     F   1 x n   which face of it, 0..5 as in the C ABI: face f at local coordinate f/2 (xi, eta,
 *                 zeta) = -1 for even f, +1 for odd f (5 is the top, zeta = +1); -1 when none
 * G, C and N are NaN, FE 0 and F -1 where the surface is farther than D (outside or deep inside).
 * cgcontact_gap(H or B, XYZ, D) (beside the MEX file) is the same call.
 *
 * 'relocate' is 'locate' warm started, for the next iteration of a solver loop: E0 and PosL0 are
 * the previous answers (as 'locate' or 'relocate' gave them; E0 0 where none). A point whose
 * element E0 still holds it costs one Newton inversion from PosL0, with no search; the others are
 * searched as 'locate' does. The answers are 'locate''s (the same elements, PosL within the Newton
 * tolerance; on a face shared by two elements either may answer), whatever the hints. An E0 that
 * is not 0 or an element of the body is an error (cgcontact:badInput).
 *
 * 'inverted_cells' lists the elements the current displacements turn inside out (det J <= 0 at a
 * corner: a node moved through its neighbours), 1-based and ascending, 1 x 0 when none. Answers
 * in or near them are not to be trusted (a point in one may get E = 0). 'update' does not check
 * for them: the check is one pass over every element, so ask when wanted.
 *
 * 'unresolved_cells' lists, the same way, the elements that f64 coordinates of their magnitude
 * cannot resolve through the current displacements: far from the origin a coordinate is known
 * only to its rounding (4 eps |x|), and an element sheared or crushed enough turns that into more
 * than a tenth of itself in PosL, so that a point that close to one of its faces may be given the
 * element beside it. `cgcontact locate` warns about them and lists them in --json.
 *
 * cgcontact_body.m (beside the MEX file) wraps these in a handle object that frees its body when
 * cleared: B = cgcontact_body(XYZ_N0, Topology); update(B, U); [E, PosL] = locate(B, XYZ).
 *
 * H is a number naming an entry of this MEX file's table; a freed handle's number is never given
 * again, so that using it is an error (cgcontact:badHandle), not another body's answers. Every
 * entry still live is freed when Octave or MATLAB exits (mexAtExit); 'free' frees one earlier.
 * The MEX file locks itself in memory (mexLock) so that `clear all` cannot unload it while
 * handles or the library's worker threads are alive; handles stay valid across `clear`.
 *
 * Copies: XYZ and XYZ_N0 are read in place (a 3 x n double array is x y z per point, the layout
 * the C ABI reads); U is read in place too (component-major). PosL is written in place by the
 * library, and E too: the library writes the elements as int64 into E's memory, converted to
 * 1-based doubles in place. Only Topology is copied (to integers, once per body).
 *
 * Bad input (wrong sizes or types, NaN, nodes not on a lattice) raises an error with
 * identifier cgcontact:* and a message naming the argument; it never crashes.
 *
 * Octave:  bash crates/cgcontact-capi/octave/build.sh OUTDIR        (then addpath(OUTDIR))
 * MATLAB:  cargo build --release -p cgcontact-capi, then, in MATLAB on Linux,
 *          mex -O -I<repo>/crates/cgcontact-capi/include cgcontact_whereami.c ...
 *              <target>/release/libcgcontact_capi.a -lpthread -ldl -lm
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mex.h"

#include "cgcontact.h"

_Static_assert(sizeof(int64_t) == sizeof(double), "cells are converted in place");

/* --- the handle table -------------------------------------------------------------------- */

typedef struct {
    cgc_body *body;
    cgc_locator *locator;
    size_t n_nodes;
    size_t n_elements;
    uint32_t fill; /* CGC_FILL_HANGING or 0, OR-ed into every update's layout */
    double generation; /* how many handles this slot gave before: part of the handle's number */
} entry;

/* A handle is slot + 1 + generation * SLOTS: a slot freed and given again gets a new number, so
 * that a freed handle still held is refused rather than answering for another body. Whole
 * numbers up to 2^53 are exact doubles: 2^20 slots and 2^33 generations each. */
#define SLOTS 1048576.0
#define GENERATIONS 8589934592.0

static entry *table = NULL;
static size_t table_len = 0;

static void free_entry(entry *e) {
    cgc_locator_free(e->locator);
    cgc_body_free(e->body);
    e->locator = NULL;
    e->body = NULL;
}

static void free_all(void) {
    for (size_t i = 0; i < table_len; i++) free_entry(&table[i]);
    free(table);
    table = NULL;
    table_len = 0;
}

/* --- errors ------------------------------------------------------------------------------- */

/* Raises an Octave/MATLAB error with the library's last message. Call after freeing anything
 * this call allocated outside mxMalloc: the error does not return. */
static void fail_cgc(cgc_error code, const char *what) {
    static const char *ids[] = {"cgcontact:ok",          "cgcontact:nullPointer",
                                "cgcontact:invalidArgument", "cgcontact:lengthMismatch",
                                "cgcontact:nonFinite",   "cgcontact:notLattice",
                                "cgcontact:nonFinitePoint", "cgcontact:internal",
                                "cgcontact:hangingConstraint"};
    const char *id = (code >= 0 && code < (int)(sizeof ids / sizeof *ids)) ? ids[code] : "cgcontact:error";
    const char *note = code == CGC_ERROR_NOT_LATTICE ? " (the library counts nodes and cells from 0)"
                       : code == CGC_ERROR_HANGING_CONSTRAINT
                           ? " (the library counts nodes from 0; here CGC_FILL_HANGING is Options.fill_hanging = true)"
                           : "";
    mexErrMsgIdAndTxt(id, "%s: %s%s", what, cgc_last_error(), note);
}

/* Octave prefixes the message with the function's name; MATLAB shows it beside. */
#define FAIL(id, ...) mexErrMsgIdAndTxt("cgcontact:" id, __VA_ARGS__)

/* An array's size, for a message: "3 x 900", every dimension of an N-d one ("3 x 1 x 2", which
 * mxGetM and mxGetN would give as 3 x 2, a size that is not refused). Written to `text`, which
 * is returned. */
static const char *dims(const mxArray *a, char *text, size_t size) {
    const mwSize *d = mxGetDimensions(a);
    size_t used = 0;
    text[0] = 0;
    for (mwSize k = 0; k < mxGetNumberOfDimensions(a) && used < size; k++) {
        int w = snprintf(text + used, size - used, k ? " x %.0f" : "%.0f", (double)d[k]);
        if (w < 0) break;
        used += (size_t)w;
    }
    return text;
}

/* How an array was given, for a message: "sparse complex double 3 x 900" (a class name alone
 * would say "double" for a complex or sparse one). Written to `text`, which is returned. */
static const char *given(const mxArray *a, char *text, size_t size) {
    char size_text[64];
    snprintf(text, size, "%s%s%s %s", mxIsSparse(a) ? "sparse " : "",
             mxIsComplex(a) ? "complex " : "", mxGetClassName(a),
             dims(a, size_text, sizeof size_text));
    return text;
}

/* A real, full double matrix with `rows` rows (0 = any); returns its column count. */
static size_t matrix(const mxArray *a, const char *name, size_t rows, const char *shape) {
    char got[96];
    if (!mxIsDouble(a) || mxIsComplex(a) || mxIsSparse(a))
        FAIL("badInput", "%s must be a real, full double matrix (%s), got %s", name, shape,
             given(a, got, sizeof got));
    if (mxGetNumberOfDimensions(a) != 2 || (rows && mxGetM(a) != rows && !mxIsEmpty(a)))
        FAIL("badSize", "%s must be %s, got %s", name, shape, dims(a, got, sizeof got));
    return mxIsEmpty(a) ? 0 : mxGetN(a);
}

/* --- options ------------------------------------------------------------------------------ */

static void settings_from(const mxArray *options, cgc_settings *s, uint32_t *fill) {
    cgc_settings_init(CGC_PRECISION_F64, s);
    *fill = 0;
    /* [] (or an empty struct array) is no options; {} or '' is a mistake of type, not "none". */
    if (!options || (mxIsEmpty(options) && (mxIsDouble(options) || mxIsStruct(options)))) return;
    if (!mxIsStruct(options) || mxGetNumberOfElements(options) != 1)
        FAIL("badInput", "Options must be a scalar struct");
    /* A misspelt field (Precision, maxiter, fillHanging) would be ignored without a word. */
    static const char *known[] = {"precision", "tol", "max_iter", "threads", "fill_hanging"};
    for (int k = 0; k < mxGetNumberOfFields(options); k++) {
        const char *name = mxGetFieldNameByNumber(options, k);
        int found = 0;
        for (size_t j = 0; j < sizeof known / sizeof *known; j++) found |= !strcmp(name, known[j]);
        if (!found)
            FAIL("badInput",
                 "Options.%s is not an option (precision, tol, max_iter, threads, fill_hanging)",
                 name);
    }
    const mxArray *f = mxGetField(options, 0, "fill_hanging");
    if (f) {
        if (!(mxIsLogical(f) || mxIsDouble(f)) || mxIsComplex(f) || mxGetNumberOfElements(f) != 1 ||
            isnan(mxGetScalar(f)))
            FAIL("badInput", "Options.fill_hanging must be true or false");
        *fill = mxGetScalar(f) != 0 ? CGC_FILL_HANGING : 0;
    }
    f = mxGetField(options, 0, "precision");
    if (f) {
        char p[8] = {0};
        if (!mxIsChar(f) || mxGetString(f, p, sizeof p) != 0 ||
            strlen(p) != mxGetNumberOfElements(f) || (strcmp(p, "f64") && strcmp(p, "f32")))
            FAIL("badInput", "Options.precision must be 'f64' or 'f32'");
        if (!strcmp(p, "f32")) cgc_settings_init(CGC_PRECISION_F32, s);
    }
    const char *numbers[] = {"tol", "max_iter", "threads"};
    for (int k = 0; k < 3; k++) {
        f = mxGetField(options, 0, numbers[k]);
        if (!f) continue;
        /* Any real class: struct('threads', int32(2)) is as much a number as 2. */
        if (!mxIsNumeric(f) || mxIsComplex(f) || mxIsSparse(f) || mxGetNumberOfElements(f) != 1) {
            char got[96];
            FAIL("badInput", "Options.%s must be a real numeric scalar, got %s", numbers[k],
                 given(f, got, sizeof got));
        }
        double v = mxGetScalar(f);
        if (k == 0) {
            s->newton_tol = v;
        } else {
            if (!(v >= 0 && v <= 4294967295.0 && v == floor(v)))
                FAIL("badInput", "Options.%s must be a whole number >= 0, got %g", numbers[k], v);
            if (k == 1) s->max_iter = (uint32_t)v;
            else s->threads = (uint32_t)v;
        }
    }
}

/* --- building, updating, locating ---------------------------------------------------------- */

/* A body and locator from XYZ_N0 (3 x m) and Topology (8 x e, 1-based). */
static entry build(const mxArray *nodes, const mxArray *topology, const mxArray *options) {
    size_t m = matrix(nodes, "XYZ_N0", 3, "3 x m, one undeformed node per column");
    size_t e = matrix(topology, "Topology", 8, "8 x e, 1-based node numbers per element");
    if (e == 0) FAIL("badSize", "Topology has no element");
    if (m == 0) FAIL("badSize", "XYZ_N0 has no node");
    const double *x = mxGetPr(nodes);
    for (size_t k = 0; k < 3 * m; k++)
        if (!isfinite(x[k]))
            FAIL("nonFinite", "XYZ_N0(%d, %d) = %g is not finite", (int)(k % 3) + 1, (int)(k / 3) + 1, x[k]);
    cgc_settings settings;
    uint32_t fill;
    settings_from(options, &settings, &fill);
    const double *t = mxGetPr(topology);
    int64_t *cells = mxMalloc(8 * e * sizeof *cells);
    for (size_t i = 0; i < 8 * e; i++) {
        if (!(t[i] == floor(t[i]) && fabs(t[i]) < 9.0e15))
            FAIL("badInput", "Topology(%d, %d) = %g is not a node number", (int)(i % 8) + 1,
                 (int)(i / 8) + 1, t[i]);
        cells[i] = (int64_t)t[i];
    }
    entry made = {.n_nodes = m, .n_elements = e, .fill = fill, .generation = 0};
    cgc_error code = cgc_body_from_mesh(mxGetPr(nodes), m, cells, e, 1, &made.body);
    mxFree(cells);
    if (code != CGC_ERROR_OK) fail_cgc(code, "XYZ_N0 and Topology");
    code = cgc_locator_new(made.body, &settings, &made.locator);
    if (code != CGC_ERROR_OK) {
        cgc_body_free(made.body);
        fail_cgc(code, "Options");
    }
    return made;
}

/* Sets U (m x 3) on the entry's body; on failure frees the entry when `owned`. An empty double U
 * leaves a body `owned` by the call (just built) undeformed; 'update' refuses it, since it would
 * keep the last displacements rather than make the body undeformed. */
static void update(entry *e, const mxArray *u, int owned) {
    if (owned && mxIsDouble(u) && mxIsEmpty(u)) return;
    if (!mxIsDouble(u) || mxIsComplex(u) || mxIsSparse(u) || mxGetNumberOfDimensions(u) != 2 ||
        mxGetM(u) != e->n_nodes || mxGetN(u) != 3) {
        char got[96];
        if (owned) free_entry(e);
        FAIL("badSize", "U must be a real, full double m x 3 matrix with m = %d nodes, got %s",
             (int)e->n_nodes, given(u, got, sizeof got));
    }
    cgc_error code = cgc_body_set_displacements(e->body, mxGetPr(u), e->n_nodes,
                                                CGC_LAYOUT_COMPONENT_MAJOR | e->fill);
    if (code != CGC_ERROR_OK) {
        if (owned) free_entry(e);
        const double *v = mxGetPr(u);
        for (size_t k = 0; code == CGC_ERROR_NON_FINITE && k < 3 * e->n_nodes; k++)
            if (!isfinite(v[k]))
                FAIL("nonFinite", "U(%d, %d) = %g is not finite", (int)(k % e->n_nodes) + 1,
                     (int)(k / e->n_nodes) + 1, v[k]);
        fail_cgc(code, "U");
    }
}

/* [E, PosL] for points XYZ (3 x n); warm started from the previous answers E0 (1 x n, 1-based, 0
 * for none) and PosL0 (3 x n) when `e0` is not NULL. */
static void locate(entry *e, const mxArray *points, const mxArray *e0, const mxArray *posl0,
                   mxArray **out, int n_out, int owned) {
    if (!mxIsDouble(points) || mxIsComplex(points) || mxIsSparse(points) ||
        mxGetNumberOfDimensions(points) != 2 || (mxGetM(points) != 3 && !mxIsEmpty(points))) {
        char got[96];
        if (owned) free_entry(e);
        FAIL("badSize", "XYZ must be a real, full double 3 x n matrix, one point per column, got %s",
             given(points, got, sizeof got));
    }
    size_t n = mxIsEmpty(points) ? 0 : mxGetN(points);
    if (e0) {
        /* Checked before anything is allocated: a bad hint costs nothing. */
        char got[96];
        if (!mxIsDouble(e0) || mxIsComplex(e0) || mxIsSparse(e0))
            FAIL("badInput", "E0 must be a real, full double vector (the last E), got %s",
                 given(e0, got, sizeof got));
        if (mxGetNumberOfDimensions(e0) != 2 || mxGetNumberOfElements(e0) != n ||
            (n > 0 && mxGetM(e0) != 1 && mxGetN(e0) != 1))
            FAIL("badSize", "E0 must be a vector of %d elements (XYZ's points), got %s", (int)n,
                 dims(e0, got, sizeof got));
        if (!mxIsDouble(posl0) || mxIsComplex(posl0) || mxIsSparse(posl0))
            FAIL("badInput", "PosL0 must be a real, full double matrix (the last PosL), got %s",
                 given(posl0, got, sizeof got));
        if (mxGetNumberOfDimensions(posl0) != 2 || mxGetNumberOfElements(posl0) != 3 * n ||
            (n > 0 && mxGetM(posl0) != 3))
            FAIL("badSize", "PosL0 must be 3 x %d, got %s", (int)n, dims(posl0, got, sizeof got));
        const double *hint = mxGetPr(e0);
        for (size_t i = 0; i < n; i++)
            if (!(hint[i] >= 0 && hint[i] <= (double)e->n_elements && hint[i] == floor(hint[i])))
                FAIL("badInput", "E0(%d) = %g is not an element number: 1 to %d, or 0 for none",
                     (int)i + 1, hint[i], (int)e->n_elements);
    }
    /* Uninitialised: the library writes every element. The cells (int64) go into E's own
     * memory, 8 bytes each as a double, and are converted in place: no temporary array. */
    mxArray *elements = mxCreateUninitNumericMatrix(1, n, mxDOUBLE_CLASS, mxREAL);
    mxArray *local = mxCreateUninitNumericMatrix(3, n, mxDOUBLE_CLASS, mxREAL);
    int64_t *cells = (int64_t *)mxGetData(elements);
    cgc_error code;
    if (e0) {
        /* The hints, 0-based, in the outputs' memory: the library reads and overwrites them. */
        const double *hint = mxGetPr(e0);
        for (size_t i = 0; i < n; i++) {
            double h = hint[i]; /* read, then overwritten as an int64 */
            cells[i] = (int64_t)h - 1;
        }
        if (n > 0) memcpy(mxGetPr(local), mxGetPr(posl0), 3 * n * sizeof(double));
        code = cgc_relocate(e->locator, mxGetPr(points), n, cells, mxGetPr(local), NULL);
    } else {
        code = cgc_locate(e->locator, mxGetPr(points), n, cells, mxGetPr(local), NULL);
    }
    if (owned) free_entry(e);
    if (code == CGC_ERROR_NON_FINITE_POINT) {
        /* The library counts from 0: name the column as Octave users count. */
        const double *p = mxGetPr(points);
        size_t k = 0;
        while (k < n && isfinite(p[3 * k]) && isfinite(p[3 * k + 1]) && isfinite(p[3 * k + 2])) k++;
        FAIL("nonFinitePoint", "XYZ(:, %d) = [%g; %g; %g] is not finite", (int)k + 1,
             p[3 * k], p[3 * k + 1], p[3 * k + 2]);
    }
    if (code != CGC_ERROR_OK) fail_cgc(code, "XYZ");
    double *E = mxGetPr(elements);
    for (size_t i = 0; i < n; i++) {
        int64_t cell = cells[i]; /* read as written, then overwritten as a double */
        E[i] = (double)(cell + 1);
    }
    out[0] = elements;
    if (n_out > 1) out[1] = local;
    else mxDestroyArray(local);
}

/* One of the body's cell lists (cgc_body_inverted_cells or cgc_body_unresolved_cells, named
 * `what` in errors), as 1-based elements, 1 x k ascending. On failure frees the entry when
 * `owned`. */
typedef cgc_error (*cell_list)(const cgc_body *, int64_t *, size_t, size_t *);
static mxArray *listed_cells(entry *e, int owned, cell_list list, const char *what) {
    size_t count = 0;
    cgc_error code = list(e->body, NULL, 0, &count);
    mxArray *out = code == CGC_ERROR_OK ? mxCreateUninitNumericMatrix(1, count, mxDOUBLE_CLASS, mxREAL) : NULL;
    /* As in locate: the int64 cells are written into the output's memory, converted in place. */
    if (out) code = list(e->body, (int64_t *)mxGetData(out), count, &count);
    if (code != CGC_ERROR_OK) {
        if (out) mxDestroyArray(out);
        if (owned) free_entry(e);
        fail_cgc(code, what);
    }
    const int64_t *cells = (const int64_t *)mxGetData(out);
    double *E = mxGetPr(out);
    for (size_t i = 0; i < count; i++) {
        int64_t cell = cells[i]; /* read as written, then overwritten as a double */
        E[i] = (double)(cell + 1);
    }
    return out;
}

/* The 1-based elements the body's displacements invert, 1 x k ascending. On failure frees the
 * entry when `owned`. */
static mxArray *inverted_cells(entry *e, int owned) {
    return listed_cells(e, owned, cgc_body_inverted_cells, "inverted_cells");
}

/* [G, C, N, FE, F] for points XYZ (3 x n) within D. */
static void gap(entry *e, const mxArray *points, const mxArray *distance, mxArray **out, int n_out) {
    size_t n = matrix(points, "XYZ", 3, "3 x n, one point per column");
    if (!mxIsDouble(distance) || mxIsComplex(distance) || mxGetNumberOfElements(distance) != 1)
        FAIL("badInput", "D must be a real double scalar");
    double d = mxGetScalar(distance);
    if (!(isfinite(d) && d >= 0)) FAIL("badInput", "D must be finite and at least 0, got %g", d);
    /* As in locate: the face's element (int64) is written into FE's own memory and converted in
     * place; the local face (int32) goes through a small array of its own. */
    mxArray *g = mxCreateUninitNumericMatrix(1, n, mxDOUBLE_CLASS, mxREAL);
    mxArray *c = mxCreateUninitNumericMatrix(3, n, mxDOUBLE_CLASS, mxREAL);
    mxArray *normal = mxCreateUninitNumericMatrix(3, n, mxDOUBLE_CLASS, mxREAL);
    mxArray *fe = mxCreateUninitNumericMatrix(1, n, mxDOUBLE_CLASS, mxREAL);
    mxArray *f = mxCreateUninitNumericMatrix(1, n, mxDOUBLE_CLASS, mxREAL);
    int64_t *cells = (int64_t *)mxGetData(fe);
    int32_t *faces = mxMalloc((n ? n : 1) * sizeof *faces);
    cgc_error code = cgc_gap(e->locator, mxGetPr(points), n, d, mxGetPr(g), mxGetPr(c),
                             mxGetPr(normal), cells, faces);
    if (code == CGC_ERROR_NON_FINITE_POINT) {
        const double *p = mxGetPr(points);
        size_t k = 0;
        while (k < n && isfinite(p[3 * k]) && isfinite(p[3 * k + 1]) && isfinite(p[3 * k + 2])) k++;
        FAIL("nonFinitePoint", "XYZ(:, %d) = [%g; %g; %g] is not finite", (int)k + 1,
             p[3 * k], p[3 * k + 1], p[3 * k + 2]);
    }
    if (code != CGC_ERROR_OK) fail_cgc(code, "gap");
    double *FE = mxGetPr(fe), *F = mxGetPr(f);
    for (size_t i = 0; i < n; i++) {
        int64_t cell = cells[i]; /* read as written, then overwritten as a double */
        FE[i] = (double)(cell + 1);
        F[i] = (double)faces[i];
    }
    mxFree(faces);
    mxArray *all[5] = {g, c, normal, fe, f};
    for (int k = 0; k < 5; k++) {
        if (k < (n_out > 1 ? n_out : 1)) out[k] = all[k];
        else mxDestroyArray(all[k]);
    }
}

/* --- handles ------------------------------------------------------------------------------- */

static entry *lookup(const mxArray *h) {
    if (!mxIsDouble(h) || mxIsComplex(h) || mxGetNumberOfElements(h) != 1)
        FAIL("badHandle", "H must be a handle from cgcontact_whereami('new', ...)");
    double v = mxGetScalar(h);
    if (!(v >= 1 && v <= SLOTS * GENERATIONS && v == floor(v)))
        FAIL("badHandle", "%.16g is not a live handle (freed, or never made)", v);
    double generation = floor((v - 1) / SLOTS);
    size_t slot = (size_t)(v - 1 - generation * SLOTS);
    if (slot >= table_len || !table[slot].body || table[slot].generation != generation)
        FAIL("badHandle", "%.16g is not a live handle (freed, or never made)", v);
    return &table[slot];
}

static double keep(entry made) {
    /* A free slot whose generations are not all spent, else a new slot. */
    size_t slot = 0;
    while (slot < table_len &&
           (table[slot].body || table[slot].generation >= GENERATIONS - 1))
        slot++;
    if (slot == table_len) {
        entry *grown =
            (double)table_len < SLOTS ? realloc(table, (table_len + 1) * sizeof *table) : NULL;
        if (!grown) {
            free_entry(&made);
            FAIL("outOfMemory", "no memory for a new handle (%d live)", (int)table_len);
        }
        table = grown;
        table[table_len++] = (entry){.body = NULL, .locator = NULL, .generation = -1};
    }
    made.generation = table[slot].generation + 1;
    table[slot] = made;
    return (double)slot + 1 + made.generation * SLOTS;
}

/* A command's arguments (lo to hi) and outputs (at most `outs`), checked before it does anything:
 * a call asking for an output the command does not give would otherwise run (update, free) and
 * only then fail, with Octave's "element number k undefined in return list". */
static void args(int nrhs, int nlhs, int lo, int hi, int outs, const char *usage) {
    if (nrhs < lo || nrhs > hi) FAIL("usage", "usage: %s", usage);
    if (nlhs > outs)
        FAIL("usage", "asked for %d output%s, the command gives %d: %s", nlhs, nlhs == 1 ? "" : "s",
             outs, usage);
}

void mexFunction(int nlhs, mxArray *plhs[], int nrhs, const mxArray *prhs[]) {
    static int locked = 0;
    if (!locked) {
        /* The library keeps worker threads: never unload it under them. */
        mexLock();
        mexAtExit(free_all);
        locked = 1;
    }
    if (nrhs >= 1 && mxIsChar(prhs[0])) {
        char command[32] = {0};
        /* A NUL inside the row ('locate' followed by char(0) and more) ends the C string
           early: the whole row must be the command. */
        if (mxGetNumberOfElements(prhs[0]) >= sizeof command || mxGetM(prhs[0]) > 1 ||
            mxGetString(prhs[0], command, sizeof command) != 0 ||
            strlen(command) != mxGetNumberOfElements(prhs[0]))
            FAIL("usage",
                 "unknown command: a row of at most %d characters (new, update, locate, "
                 "relocate, gap, inverted_cells, unresolved_cells, query_seconds, free, handles)",
                 (int)sizeof command - 1);
        if (!strcmp(command, "new")) {
            args(nrhs, nlhs, 3, 4, 1, "H = cgcontact_whereami('new', XYZ_N0, Topology [, Options])");
            entry made = build(prhs[1], prhs[2], nrhs > 3 ? prhs[3] : NULL);
            plhs[0] = mxCreateDoubleScalar(keep(made));
        } else if (!strcmp(command, "update")) {
            args(nrhs, nlhs, 3, 3, 0, "cgcontact_whereami('update', H, U)");
            update(lookup(prhs[1]), prhs[2], 0);
        } else if (!strcmp(command, "locate")) {
            args(nrhs, nlhs, 3, 3, 2, "[E, PosL] = cgcontact_whereami('locate', H, XYZ)");
            locate(lookup(prhs[1]), prhs[2], NULL, NULL, plhs, nlhs, 0);
        } else if (!strcmp(command, "relocate")) {
            args(nrhs, nlhs, 5, 5, 2, "[E, PosL] = cgcontact_whereami('relocate', H, XYZ, E0, PosL0)");
            locate(lookup(prhs[1]), prhs[2], prhs[3], prhs[4], plhs, nlhs, 0);
        } else if (!strcmp(command, "gap")) {
            args(nrhs, nlhs, 4, 4, 5, "[G, C, N, FE, F] = cgcontact_whereami('gap', H, XYZ, D)");
            gap(lookup(prhs[1]), prhs[2], prhs[3], plhs, nlhs);
        } else if (!strcmp(command, "inverted_cells")) {
            args(nrhs, nlhs, 2, 2, 1, "Inverted = cgcontact_whereami('inverted_cells', H)");
            plhs[0] = inverted_cells(lookup(prhs[1]), 0);
        } else if (!strcmp(command, "unresolved_cells")) {
            args(nrhs, nlhs, 2, 2, 1, "Unresolved = cgcontact_whereami('unresolved_cells', H)");
            plhs[0] = listed_cells(lookup(prhs[1]), 0, cgc_body_unresolved_cells, "unresolved_cells");
        } else if (!strcmp(command, "query_seconds")) {
            args(nrhs, nlhs, 3, 4, 1, "S = cgcontact_whereami('query_seconds', H, XYZ [, Repeats])");
            entry *e = lookup(prhs[1]);
            size_t n = matrix(prhs[2], "XYZ", 3, "3 x n, one point per column");
            if (nrhs > 3 && (!mxIsDouble(prhs[3]) || mxIsComplex(prhs[3]) ||
                             mxGetNumberOfElements(prhs[3]) != 1))
                FAIL("badInput", "Repeats must be a real double scalar");
            double repeats = nrhs > 3 ? mxGetScalar(prhs[3]) : 0;
            if (!(repeats >= 0 && repeats < 1e6 && repeats == floor(repeats)))
                FAIL("badInput", "Repeats must be a whole number in [0, 1e6)");
            double seconds = 0;
            cgc_error code = cgc_locator_query_seconds(e->locator, mxGetPr(prhs[2]), n, (uint32_t)repeats, &seconds);
            if (code != CGC_ERROR_OK) fail_cgc(code, "XYZ");
            plhs[0] = mxCreateDoubleScalar(seconds);
        } else if (!strcmp(command, "free")) {
            args(nrhs, nlhs, 2, 2, 0, "cgcontact_whereami('free', H)");
            free_entry(lookup(prhs[1]));
        } else if (!strcmp(command, "handles")) {
            args(nrhs, nlhs, 1, 1, 1, "N = cgcontact_whereami('handles')");
            double live = 0;
            for (size_t i = 0; i < table_len; i++) live += table[i].body != NULL;
            plhs[0] = mxCreateDoubleScalar(live);
        } else {
            FAIL("usage", "unknown command '%s' (new, update, locate, relocate, gap, inverted_cells, unresolved_cells, query_seconds, free, handles)", command);
        }
        return;
    }
    args(nrhs, nlhs, 3, 5, 3, "[E, PosL, Inverted] = cgcontact_whereami(XYZ, XYZ_N0, Topology, U [, Options])");
    /* Check the points before building anything, so that a bad XYZ costs nothing. */
    matrix(prhs[0], "XYZ", 3, "3 x n, one point per column");
    entry made = build(prhs[1], prhs[2], nrhs > 4 ? prhs[4] : NULL);
    if (nrhs > 3) update(&made, prhs[3], 1);
    /* Only when asked for: the check is a pass over every element. */
    if (nlhs > 2) plhs[2] = inverted_cells(&made, 1);
    locate(&made, prhs[0], NULL, NULL, plhs, nlhs, 1);
}
