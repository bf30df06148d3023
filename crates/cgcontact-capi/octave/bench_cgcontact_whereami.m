% Overhead of the MEX call over the Rust library's own query time, measured in the same run:
%
%   bash crates/cgcontact-capi/octave/build.sh /tmp/cgc-mex
%   CGCONTACT_MEX_DIR=/tmp/cgc-mex octave-cli --quiet crates/cgcontact-capi/octave/bench_cgcontact_whereami.m
%
% A 50 x 50 x 50 block (125,000 cells, 132,651 nodes) with a smooth displacement of up to 0.4 h,
% and 1,000,000 random points inside it. 'locate' is timed from Octave (tic/toc around the call:
% argument checks, output allocation, the query, the conversion of cells to 1-based doubles);
% 'query_seconds' times the library's locate_all_into on the same points and locator. Both are
% the shortest of 9 runs, interleaved. The library's runs reuse a warm answer buffer (as a solver
% loop does); the MEX call returns fresh Octave arrays every time.
1;
addpath(getenv('CGCONTACT_MEX_DIR'));
nc = 50; h = 0.2;
[I, J, K] = ndgrid(0:nc, 0:nc, 0:nc);
N0 = h * [I(:) J(:) K(:)]';
node = @(i, j, k) 1 + i + (nc + 1) * (j + (nc + 1) * k);
[ci, cj, ck] = ndgrid(0:nc - 1, 0:nc - 1, 0:nc - 1);
ci = ci(:)'; cj = cj(:)'; ck = ck(:)';
corners = [0 0 0; 1 0 0; 1 1 0; 0 1 0; 0 0 1; 1 0 1; 1 1 1; 0 1 1];
T = zeros(8, numel(ci));
for c = 1:8
  T(c, :) = node(ci + corners(c, 1), cj + corners(c, 2), ck + corners(c, 3));
end
U = 0.4 * h * [sin(0.7 * N0(2, :)); cos(0.5 * N0(1, :)) .* sin(0.4 * N0(3, :)); -sin(0.6 * N0(1, :))]';
rand('seed', 1);
n = 1e6;
XYZ = h + (nc - 2) * h * rand(3, n);

Hd = cgcontact_whereami('new', N0, T);
cgcontact_whereami('update', Hd, U);
runs = 9;
t = zeros(1, runs);
q = zeros(1, runs);
for r = 1:runs   % interleaved, so that a busy machine slows both alike
  tic; [E, PosL] = cgcontact_whereami('locate', Hd, XYZ); t(r) = toc;
  q(r) = cgcontact_whereami('query_seconds', Hd, XYZ, 1);   % one warm-up, one timed run
end
library = min(q);
% The same call on points far outside the body, which the library rejects at once: what is left
% is the cost of returning E and PosL to Octave (Octave copies a MEX file's outputs, 32 bytes per
% point) and this MEX file's own work.
FAR = XYZ + 1e3;
tf = zeros(1, runs);
qf = zeros(1, runs);
for r = 1:runs
  tic; [Ef, Pf] = cgcontact_whereami('locate', Hd, FAR); tf(r) = toc;
  qf(r) = cgcontact_whereami('query_seconds', Hd, FAR, 1);
end
assert(all(Ef == 0));
tic; [E1, P1] = cgcontact_whereami(XYZ, N0, T, U); one_shot = toc;
assert(isequal(E, E1) && isequaln(PosL, P1));
printf('%d points, %d located, %d cells, %d threads\n', n, sum(E > 0), columns(T), nproc());
printf('MEX locate (handle):       %.2f ms (min of %d; median %.2f ms)\n', 1e3 * min(t), runs, 1e3 * median(t));
printf('library query (same run):  %.2f ms (min of %d; median %.2f ms)\n', 1e3 * library, runs, 1e3 * median(q));
printf('overhead:                  %.1f %%\n', 100 * (min(t) / library - 1));
printf('points outside the body:   MEX %.2f ms, library %.2f ms (the cost of returning the outputs)\n', ...
       1e3 * min(tf), 1e3 * min(qf));
printf('one-shot call (builds the body from XYZ_N0 and Topology too): %.2f ms\n', 1e3 * one_shot);
