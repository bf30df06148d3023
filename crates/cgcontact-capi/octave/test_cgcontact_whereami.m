% Octave test of cgcontact_whereami, run by .ci/run:
%
%   CGCONTACT_MEX_DIR=DIR CGCONTACT_BIN=path/to/cgcontact octave-cli test_cgcontact_whereami.m
%
% Builds a lattice block with a smooth displacement here in Octave, writes it as a legacy ASCII
% .vtk mesh and a points CSV, runs `cgcontact locate` on them, and checks that the MEX file gives
% the same answers: the same cells, xi within 1e-12. A node moved through its neighbour inverts
% the elements known by construction, which 'inverted_cells' lists as `cgcontact locate --json`
% does. Then the same for an adaptive block (three refinement levels, hanging nodes set by the
% Q1 rule), and the hanging-node error. Then the gaps of points to a 2 x 2 x 2 block (known
% answers), and that bad inputs raise errors.
% Any failure ends Octave with a non-zero exit status.
1;

function check(ok, varargin)
  if ~ok
    fprintf(2, 'FAILED: %s\n', sprintf(varargin{:}));
    exit(1);
  end
end

function expect_error(id, f, what, text)
  % With `text`, the message must hold it too.
  try
    f();
  catch err
    check(strcmp(err.identifier, id), '%s: expected error %s, got %s (%s)', what, id, ...
          err.identifier, err.message);
    check(nargin < 4 || ~isempty(strfind(err.message, text)), '%s: expected ''%s'' in: %s', ...
          what, text, err.message);
    printf('  %-40s -> %s: %s\n', what, err.identifier, err.message);
    return;
  end
  check(false, '%s: expected error %s, got none', what, id);
end

function ask_outputs(k, varargin)
  % cgcontact_whereami(varargin{:}) asked for k outputs.
  out = cell(1, k);
  [out{:}] = cgcontact_whereami(varargin{:});
end

function [N0, T, U] = scene(nc, h, origin)
  % Nodes of an nc(1) x nc(2) x nc(3) lattice, numbered in reverse order; cells in reverse order.
  [I, J, K] = ndgrid(0:nc(1), 0:nc(2), 0:nc(3));
  ijk = [I(:) J(:) K(:)]';
  m = columns(ijk);
  node = @(i, j, k) 1 + i + (nc(1) + 1) * (j + (nc(2) + 1) * k);
  renumber = m:-1:1;                               % node n becomes node renumber(n)
  N0 = zeros(3, m);
  N0(:, renumber) = origin(:) + h(:) .* ijk;
  [ci, cj, ck] = ndgrid(0:nc(1) - 1, 0:nc(2) - 1, 0:nc(3) - 1);
  ci = ci(:)'; cj = cj(:)'; ck = ck(:)';
  corners = [0 0 0; 1 0 0; 1 1 0; 0 1 0; 0 0 1; 1 0 1; 1 1 1; 0 1 1];
  T = zeros(8, numel(ci));
  for c = 1:8
    T(c, :) = renumber(node(ci + corners(c, 1), cj + corners(c, 2), ck + corners(c, 3)));
  end
  T = fliplr(T);
  % A smooth displacement of up to about 0.4 of a cell.
  X = N0(1, :); Y = N0(2, :); Z = N0(3, :);
  U = [0.4 * h(1) * sin(0.7 * Y + 0.3 * Z); 0.3 * h(2) * cos(0.5 * X) .* sin(0.4 * Z); ...
       -0.35 * h(3) * sin(0.6 * X + 0.2 * Y)]';
end

function [N0, T, U, hanging] = adaptive_scene(h, origin)
  % A 2 x 2 x 2 block of base cells h: base cell (0,0,0) halved, its upper child halved again
  % (level 2 beside level 0: unbalanced), base cell (1,0,1) halved. Nodes and cells shuffled.
  % U is smooth at the independent nodes; each hanging node gets the trilinear interpolation of
  % the coarse cell it hangs on (edge midpoints the mean of 2 nodes, face centres of 4),
  % coarsest cells first so that a coarse cell's own hanging corners are set before it is used.
  % hanging: 1 x m logical, the hanging nodes.
  L = 2;
  bits = @(c) double(bitand(c, [1 2 4]) > 0);
  leaves = zeros(0, 4);                            % level, i, j, k on the level's lattice
  for k = 0:1
    for j = 0:1
      for i = 0:1
        if isequal([i j k], [0 0 0])
          for c = 0:7
            child = 2 * [i j k] + bits(c);
            if isequal(child, [1 1 1])
              for g = 0:7
                leaves(end + 1, :) = [2, 2 * child + bits(g)];
              end
            else
              leaves(end + 1, :) = [1, child];
            end
          end
        elseif isequal([i j k], [1 0 1])
          for c = 0:7
            leaves(end + 1, :) = [1, 2 * [i j k] + bits(c)];
          end
        else
          leaves(end + 1, :) = [0 i j k];
        end
      end
    end
  end
  e = rows(leaves);
  corners = [0 0 0; 1 0 0; 1 1 0; 0 1 0; 0 0 1; 1 0 1; 1 1 1; 0 1 1];
  s = 2 .^ (L - leaves(:, 1));                     % a leaf's edge in finest steps
  allq = zeros(8 * e, 3);
  for c = 1:8
    allq(c:8:end, :) = (leaves(:, 2:4) + corners(c, :)) .* s;
  end
  [Q, ~, idx] = unique(allq, 'rows');
  T = reshape(idx, 8, e);
  m = rows(Q);
  N0 = origin(:) + h(:) .* Q' / 2^L;
  X = N0(1, :); Y = N0(2, :); Z = N0(3, :);
  U = [0.3 * h(1) * sin(0.7 * Y + 0.3 * Z); 0.25 * h(2) * cos(0.5 * X) .* sin(0.4 * Z); ...
       -0.3 * h(3) * sin(0.6 * X + 0.2 * Y)]';
  hanging = false(1, m);
  [~, coarse_first] = sort(leaves(:, 1));
  for l = coarse_first'
    lo = leaves(l, 2:4) * s(l);
    t = (Q - lo) / s(l);                           % local coordinates in [0, 1] on the box
    on_box = all(t >= 0 & t <= 1, 2);
    corner = all(t == 0 | t == 1, 2);
    for n = find(on_box & ~corner)'
      w = prod(corners .* t(n, :) + (1 - corners) .* (1 - t(n, :)), 2);   % 8 x 1
      U(n, :) = w' * U(T(:, l), :);
      hanging(n) = true;
    end
  end
  % Shuffle: node n becomes node p(n); cells in a random order.
  p = randperm(m);
  N0(:, p) = N0; U(p, :) = U; hanging(p) = hanging;
  T = p(T(:, randperm(e)));
end

function write_vtk(path, N0, T, U)
  f = fopen(path, 'w');
  fprintf(f, '# vtk DataFile Version 3.0\ncgcontact octave test\nASCII\nDATASET UNSTRUCTURED_GRID\n');
  fprintf(f, 'POINTS %d double\n', columns(N0));
  fprintf(f, '%.17g %.17g %.17g\n', N0);
  fprintf(f, 'CELLS %d %d\n', columns(T), 9 * columns(T));
  fprintf(f, '8 %d %d %d %d %d %d %d %d\n', T - 1);
  fprintf(f, 'CELL_TYPES %d\n', columns(T));
  fprintf(f, '%d\n', 12 * ones(1, columns(T)));
  fprintf(f, 'POINT_DATA %d\nVECTORS displacement double\n', columns(N0));
  fprintf(f, '%.17g %.17g %.17g\n', U');
  fclose(f);
end

mex_dir = getenv('CGCONTACT_MEX_DIR');
cli = getenv('CGCONTACT_BIN');
check(~isempty(mex_dir) && ~isempty(cli), 'set CGCONTACT_MEX_DIR and CGCONTACT_BIN');
addpath(mex_dir);
work = tempname();
mkdir(work);

% --- the scene, and the command line's answers --------------------------------------------
nc = [12 10 8]; h = [0.5 0.4 0.3]; origin = [1e3 -2 3];
[N0, T, U] = scene(nc, h, origin);
rand('seed', 42);
n = 20000;
low = origin(:) - 0.1 * h(:) .* nc(:);
high = origin(:) + 1.1 * h(:) .* nc(:);
XYZ = low + (high - low) .* rand(3, n);            % inside and outside the body
XYZ(:, 1:5) = N0(:, T(1:5, 7)) + U(T(1:5, 7), :)';   % deformed nodes: on shared corners
write_vtk(fullfile(work, 'mesh.vtk'), N0, T, U);
f = fopen(fullfile(work, 'points.csv'), 'w');
fprintf(f, 'x,y,z\n');
fprintf(f, '%.17g,%.17g,%.17g\n', XYZ);
fclose(f);
cmd = sprintf('"%s" locate --mesh "%s" --points "%s" --out "%s" --quiet', cli, ...
              fullfile(work, 'mesh.vtk'), fullfile(work, 'points.csv'), fullfile(work, 'results.csv'));
[status, output] = system(cmd);
check(status == 0, 'cgcontact locate failed (%d): %s', status, output);
R = dlmread(fullfile(work, 'results.csv'), ',', 1, 0);   % point,cell,xi,eta,zeta,...
check(rows(R) == n, 'results: %d rows for %d points', rows(R), n);
cli_E = R(:, 2)' + 1;                              % -1 (none) becomes 0
cli_PosL = R(:, 3:5)';

% --- the one-shot call --------------------------------------------------------------------
[E, PosL] = cgcontact_whereami(XYZ, N0, T, U);
check(isequal(size(E), [1 n]) && isequal(size(PosL), [3 n]), 'output sizes');
check(isequal(E, cli_E), 'cells differ from cgcontact locate at %d points', sum(E ~= cli_E));
found = E > 0;
check(all(isnan(PosL(:, ~found))(:)), 'points not found must have NaN PosL');
err = max(max(abs(PosL(:, found) - cli_PosL(:, found))));
check(err <= 1e-12, 'xi differs from cgcontact locate by %g', err);
check(all(abs(PosL(:, found))(:) <= 1 + 1e-9), 'xi outside [-1, 1]');
printf('one-shot: %d points, %d located, cells as cgcontact locate, max xi difference %.3g\n', ...
       n, sum(found), err);

% --- handles: build once, update, locate --------------------------------------------------
H = cgcontact_whereami('new', N0, T);
[E0, P0] = cgcontact_whereami('locate', H, XYZ);
[E0b, P0b] = cgcontact_whereami(XYZ, N0, T, []);
check(isequal(E0, E0b) && isequaln(P0, P0b), 'handle, undeformed: differs from the one-shot call');
cgcontact_whereami('update', H, U);
[E1, P1] = cgcontact_whereami('locate', H, XYZ);
check(isequal(E1, E) && isequaln(P1, PosL), 'handle after update: differs from the one-shot call');
check(~isequal(E0, E1), 'the update changed nothing');
opts = struct('precision', 'f32', 'threads', 1);
H32 = cgcontact_whereami('new', N0, T, opts);
cgcontact_whereami('update', H32, U);
[E32, P32] = cgcontact_whereami('locate', H32, XYZ);
inner = found & E32 > 0;
check(mean(E32 == E) > 0.999, 'f32 cells: %d differ', sum(E32 ~= E));
check(max(max(abs(P32(:, inner & E32 == E) - PosL(:, inner & E32 == E)))) < 1e-4, 'f32 xi');
check(cgcontact_whereami('handles') == 2, 'two live handles');
cgcontact_whereami('free', H32);
check(cgcontact_whereami('handles') == 1, 'one live handle after free');
B = cgcontact_body(N0, T);
check(cgcontact_whereami('handles') == 2, 'cgcontact_body makes a handle');
update(B, U);
[EB, PB] = locate(B, XYZ);
check(isequal(EB, E) && isequaln(PB, PosL), 'cgcontact_body differs from the one-shot call');
clear B;
check(cgcontact_whereami('handles') == 1, 'clear frees the cgcontact_body''s handle');
printf('handles: new, update, locate agree with the one-shot call; f32 within 1e-4; cgcontact_body frees itself\n');

% --- warm starts: the next iteration from the last answers ----------------------------------
% The field grows by a tenth; 'relocate' from the answers of the old field gives the elements
% of a cold 'locate' of the new one, whatever the hints (the last answers, none, wrong ones).
cgcontact_whereami('update', H, 1.1 * U);
[Ec, Pc] = cgcontact_whereami('locate', H, XYZ);
check(~isequal(Ec, E1), 'the grown field changed nothing');
foundc = Ec > 0;
wrong = mod((1:n) * 37, columns(T)) + 1;
hints = {E1, P1, 'the last answers'; zeros(1, n), NaN(3, n), 'none'; wrong, zeros(3, n), 'wrong elements'};
for k = 1:rows(hints)
  [Ew, Pw] = cgcontact_whereami('relocate', H, XYZ, hints{k, 1}, hints{k, 2});
  check(isequal(Ew, Ec), 'relocate (%s): elements differ from locate at %d points', hints{k, 3}, sum(Ew ~= Ec));
  check(all(isnan(Pw(:, ~foundc))(:)), 'relocate (%s): points not found must have NaN PosL', hints{k, 3});
  check(max(max(abs(Pw(:, foundc) - Pc(:, foundc)))) <= 1e-12, 'relocate (%s): PosL differs', hints{k, 3});
end
[Ew, Pw] = cgcontact_whereami('relocate', H, XYZ, zeros(n, 1), NaN(3, n));
check(isequal(Ew, Ec) && isequaln(Pw, Pc), 'relocate without hints (a column E0): not locate''s answers');
% The hint is tried first, in Octave's numbering: a deformed node shared by several elements is
% answered by whichever of them E0 names.
cgcontact_whereami('update', H, U);
[~, node] = max(accumarray(T(:), 1));   % a node of the most elements (8 inside the block)
owners = find(any(T == node, 1));
check(numel(owners) == 8, 'node %d is in %d elements only', node, numel(owners));
x = N0(:, node) + U(node, :)';
for o = owners
  [Eo, Po] = cgcontact_whereami('relocate', H, x, o, [0; 0; 0]);
  check(Eo == o, 'relocate at a shared node: element %d answered, %d hinted', Eo, o);
  check(all(abs(abs(Po) - 1) < 1e-12), 'relocate at a shared node: PosL %s is no corner', mat2str(Po'));
end
expect_error('cgcontact:badInput', @() cgcontact_whereami('relocate', H, XYZ, E1 .* (1:n ~= 3) - (1:n == 3), P1), 'relocate, E0 = -1');
expect_error('cgcontact:badInput', @() cgcontact_whereami('relocate', H, XYZ, E1 + 0.5, P1), 'relocate, E0 not whole');
expect_error('cgcontact:badInput', @() cgcontact_whereami('relocate', H, XYZ, E1 + columns(T) * (1:n == 4), P1), 'relocate, E0 past the last element');
expect_error('cgcontact:badSize', @() cgcontact_whereami('relocate', H, XYZ, E1(1:end-1), P1), 'relocate, E0 short');
expect_error('cgcontact:badSize', @() cgcontact_whereami('relocate', H, XYZ, E1, P1'), 'relocate, PosL0 n x 3');
expect_error('cgcontact:badInput', @() cgcontact_whereami('relocate', H, XYZ, single(E1), P1), 'relocate, E0 single');
expect_error('cgcontact:usage', @() cgcontact_whereami('relocate', H, XYZ, E1), 'relocate without PosL0');
B = cgcontact_body(N0, T);
update(B, U);
[EB, PB] = locate(B, XYZ);
[EB2, PB2] = relocate(B, XYZ, EB, PB);
check(isequal(EB2, EB) && max(max(abs(PB2(:, EB > 0) - PB(:, EB > 0)))) <= 1e-12, 'cgcontact_body relocate');
clear B;
printf('relocate: from the last answers, none or wrong ones, the elements of locate; hints in 1-based numbering tried first\n');

% --- inverted elements: a node moved through its neighbour ---------------------------------
% Lattice node (5, 4, 3) moved 1.5 cells in x, through its neighbour (6, 4, 3): the four elements
% with it at their -x corners, cells (5, 3..4, 2..3), are inverted there; the four at i = 4 only
% stretch. The scene numbers nodes and elements in reverse (node n is m + 1 - n, element c is
% e + 1 - c, counting i fastest from 1).
check(isequal(cgcontact_whereami('inverted_cells', H), zeros(1, 0)), ...
      'the smoothly deformed block has inverted elements: %s', ...
      mat2str(cgcontact_whereami('inverted_cells', H)));
m = columns(N0); e = columns(T);
moved = m + 1 - (1 + 5 + (nc(1) + 1) * (4 + (nc(2) + 1) * 3));
check(isequal(N0(:, moved), origin(:) + h(:) .* [5; 4; 3]), 'the node to move is not (5, 4, 3)');
[cj, ck] = ndgrid(3:4, 2:3);
expected = sort(e + 1 - (1 + 5 + nc(1) * (cj(:)' + nc(2) * ck(:)')));
Ui = U; Ui(moved, 1) = Ui(moved, 1) + 1.5 * h(1);
cgcontact_whereami('update', H, Ui);
inverted = cgcontact_whereami('inverted_cells', H);
check(isequal(inverted, expected), 'inverted elements %s, expected %s', mat2str(inverted), ...
      mat2str(expected));
[~, ~, inverted1] = cgcontact_whereami(XYZ, N0, T, Ui);
check(isequal(inverted1, expected), 'one-shot: inverted elements %s', mat2str(inverted1));
[~, ~, none] = cgcontact_whereami(XYZ, N0, T, U);
check(isequal(none, zeros(1, 0)), 'one-shot: inverted elements of the smooth block %s', mat2str(none));
B = cgcontact_body(N0, T);
update(B, Ui);
check(isequal(inverted_cells(B), expected), 'cgcontact_body: inverted elements %s', ...
      mat2str(inverted_cells(B)));
clear B;
% The command line's list for the same mesh: `inverted_cells` of its --json summary, 0-based.
write_vtk(fullfile(work, 'inverted.vtk'), N0, T, Ui);
cmd = sprintf('"%s" locate --mesh "%s" --points "%s" --json --quiet', cli, ...
              fullfile(work, 'inverted.vtk'), fullfile(work, 'points.csv'));
[status, output] = system(cmd);
check(status == 0, 'cgcontact locate (inverted) failed (%d): %s', status, output);
summary = jsondecode(output);
cli_inverted = sort(summary.inverted_cells(:)') + 1;
check(isequal(inverted, cli_inverted), 'inverted elements %s, cgcontact locate %s', ...
      mat2str(inverted), mat2str(cli_inverted));
cgcontact_whereami('update', H, U);
check(isequal(cgcontact_whereami('inverted_cells', H), zeros(1, 0)), 'the list follows the displacements');
expect_error('cgcontact:usage', @() cgcontact_whereami('inverted_cells', H, U), 'inverted_cells with U');
printf('inverted: elements %s, as constructed and as cgcontact locate --json; none when undone\n', ...
       mat2str(inverted));

% --- elements f64 cannot resolve: far from the origin, thin and sheared ----------------------
% Three elements along x at (-1e7)^3, 1.6e-5 thin along z; u_z = s (Y - Y0) on the nodes at
% i <= 1: lattice cell 0 sheared by dz/dy = s, cell 1 by s / 2 at its centre, cell 2 not at all.
% A rounding of y (4 eps |x| = 8.9e-9) moves xi_z by about 1.1e-3 s in cell 0: with s = 1000
% cells 0 and 1 (elements 3 and 2, the scene numbering in reverse) exceed a tenth of the cell;
% with s = 10 none does. `cgcontact locate --json` lists the same cells.
hr = [0.03125 0.001953125 1.5625e-5]; orr = [-1e7 -1e7 -1e7];
[N0r, Tr] = scene([3 1 1], hr, orr);
ir = round((N0r(1, :) - orr(1)) / hr(1));
Hr = cgcontact_whereami('new', N0r, Tr);
check(isequal(cgcontact_whereami('unresolved_cells', Hr), zeros(1, 0)), 'undeformed: unresolved %s', ...
      mat2str(cgcontact_whereami('unresolved_cells', Hr)));
for shear = [1e3 10]
  Ur = zeros(columns(N0r), 3);
  Ur(:, 3) = shear * (ir <= 1)' .* (N0r(2, :) - orr(2))';
  cgcontact_whereami('update', Hr, Ur);
  unresolved = cgcontact_whereami('unresolved_cells', Hr);
  expected = zeros(1, 0);
  if shear > 100, expected = [2 3]; end
  check(isequal(unresolved, expected), 'shear %g: unresolved elements %s, expected %s', shear, ...
        mat2str(unresolved), mat2str(expected));
  write_vtk(fullfile(work, 'unresolved.vtk'), N0r, Tr, Ur);
  fid = fopen(fullfile(work, 'far.csv'), 'w'); fprintf(fid, 'x,y,z\n-1e7,-1e7,-1e7\n'); fclose(fid);
  cmd = sprintf('"%s" locate --mesh "%s" --points "%s" --json --quiet', cli, ...
                fullfile(work, 'unresolved.vtk'), fullfile(work, 'far.csv'));
  [status, output] = system(cmd);
  check(status == 0, 'cgcontact locate (unresolved) failed (%d): %s', status, output);
  summary = jsondecode(output);
  cli_unresolved = sort(summary.unresolved_cells(:)') + 1;
  check(isequal(unresolved, reshape(cli_unresolved, 1, [])), ...
        'unresolved elements %s, cgcontact locate %s', mat2str(unresolved), mat2str(cli_unresolved));
end
B = cgcontact_body(N0r, Tr);
Ur(:, 3) = 1e3 * (ir <= 1)' .* (N0r(2, :) - orr(2))';
update(B, Ur);
check(isequal(unresolved_cells(B), [2 3]), 'cgcontact_body: unresolved elements %s', ...
      mat2str(unresolved_cells(B)));
clear B;
expect_error('cgcontact:usage', @() cgcontact_whereami('unresolved_cells', Hr, Ur), 'unresolved_cells with U');
cgcontact_whereami('free', Hr);
expect_error('cgcontact:badHandle', @() cgcontact_whereami('unresolved_cells', Hr), 'unresolved_cells, a freed handle');
printf('unresolved: elements [2 3] at -1e7 sheared by 1000, none by 10, as cgcontact locate --json\n');

% --- an adaptive mesh: the same calls, the same answers as cgcontact locate -----------------
ha = [0.6 0.5 0.4]; oa = [-3 1 2];
[N0a, Ta, Ua, hanging] = adaptive_scene(ha, oa);
na = 6000;
XYZa = oa(:) - 0.1 * 2 * ha(:) + 1.2 * 2 * ha(:) .* rand(3, na);
XYZa = [XYZa, N0a(:, hanging) + Ua(hanging, :)'];   % and every deformed hanging node
na = columns(XYZa);
write_vtk(fullfile(work, 'adaptive.vtk'), N0a, Ta, Ua);
f = fopen(fullfile(work, 'adaptive.csv'), 'w');
fprintf(f, 'x,y,z\n');
fprintf(f, '%.17g,%.17g,%.17g\n', XYZa);
fclose(f);
% --strict: the command line refuses hanging nodes off their constraint, so this also checks
% that the scene's Q1 rule is the library's.
cmd = sprintf('"%s" locate --mesh "%s" --points "%s" --out "%s" --quiet --strict', cli, ...
              fullfile(work, 'adaptive.vtk'), fullfile(work, 'adaptive.csv'), ...
              fullfile(work, 'adaptive_results.csv'));
[status, output] = system(cmd);
check(status == 0, 'cgcontact locate (adaptive) failed (%d): %s', status, output);
R = dlmread(fullfile(work, 'adaptive_results.csv'), ',', 1, 0);
check(rows(R) == na, 'adaptive results: %d rows for %d points', rows(R), na);
cli_Ea = R(:, 2)' + 1;
cli_PosLa = R(:, 3:5)';
[Ea, PosLa] = cgcontact_whereami(XYZa, N0a, Ta, Ua);
check(isequal(Ea, cli_Ea), 'adaptive: cells differ from cgcontact locate at %d points', sum(Ea ~= cli_Ea));
founda = Ea > 0;
check(all(isnan(PosLa(:, ~founda))(:)), 'adaptive: points not found must have NaN PosL');
erra = max(max(abs(PosLa(:, founda) - cli_PosLa(:, founda))));
check(erra <= 1e-12, 'adaptive: xi differs from cgcontact locate by %g', erra);
check(all(Ea(end - sum(hanging) + 1:end) > 0), 'adaptive: a deformed hanging node not found');
check(numel(unique(Ea(founda))) > 0.9 * columns(Ta), 'adaptive: most elements hold some point');
printf('adaptive: %d elements (3 levels), %d hanging nodes, %d points, %d located, as cgcontact locate, max xi difference %.3g\n', ...
       columns(Ta), sum(hanging), na, sum(founda), erra);
Ha = cgcontact_whereami('new', N0a, Ta);
cgcontact_whereami('update', Ha, Ua);
[Eh, Ph] = cgcontact_whereami('locate', Ha, XYZa);
check(isequal(Eh, Ea) && isequaln(Ph, PosLa), 'adaptive handle: differs from the one-shot call');
Ba = cgcontact_body(N0a, Ta, struct('threads', 2));
update(Ba, Ua);
[Eb, Pb] = locate(Ba, XYZa);
check(isequal(Eb, Ea) && isequaln(Pb, PosLa), 'adaptive cgcontact_body: differs from the one-shot call');
% A hanging node off its constraint: the documented error (names the count and the worst node),
% and the handle keeps its displacements; Options.fill_hanging fills it instead.
hn = find(hanging);
off = Ua; off(hn(4), 2) = off(hn(4), 2) + 1e-3 * ha(2);
expect_error('cgcontact:hangingConstraint', @() cgcontact_whereami(XYZa, N0a, Ta, off), 'a hanging node off its constraint');
expect_error('cgcontact:hangingConstraint', @() cgcontact_whereami('update', Ha, off), 'update: a hanging node off');
raised = false;
try
  cgcontact_whereami('update', Ha, off);
catch err
  raised = true;
  named = sprintf('1 of %d hanging nodes', sum(hanging));
  worst = sprintf('node %d (0-based)', hn(4) - 1);
  check(~isempty(strfind(err.message, named)) && ~isempty(strfind(err.message, worst)) && ...
        ~isempty(strfind(err.message, 'Options.fill_hanging')), 'hanging error message: %s', err.message);
end
check(raised, 'update: a hanging node off its constraint raised no error');
[Eh, Ph] = cgcontact_whereami('locate', Ha, XYZa);
check(isequal(Eh, Ea) && isequaln(Ph, PosLa), 'adaptive handle: a refused update changed it');
wild = Ua; wild(hn, :) = 7;                        % ignored when filled
[Ef, Pf] = cgcontact_whereami(XYZa, N0a, Ta, wild, struct('fill_hanging', true));
check(isequal(Ef, Ea), 'fill_hanging: cells differ at %d points', sum(Ef ~= Ea));
check(max(max(abs(Pf(:, founda) - PosLa(:, founda)))) <= 1e-12, 'fill_hanging: xi differs');
expect_error('cgcontact:badInput', @() cgcontact_whereami(XYZa, N0a, Ta, Ua, struct('fill_hanging', 'yes')), 'Options.fill_hanging');
Tover = [Ta, Ta(:, 1)];                            % an element listed twice: an overlap
expect_error('cgcontact:notLattice', @() cgcontact_whereami(XYZa, N0a, Tover, []), 'adaptive: an element twice');
cgcontact_whereami('free', Ha);
clear Ba;
printf('adaptive: handles agree; a hanging node off its constraint is refused; fill_hanging fills it\n');

% --- gaps: known answers on a 2 x 2 x 2 block of unit cells --------------------------------
[I, J, K] = ndgrid(0:2, 0:2, 0:2);
Ng = [I(:) J(:) K(:)]';                          % node 1 + i + 3 (j + 3 k)
corners = [0 0 0; 1 0 0; 1 1 0; 0 1 0; 0 0 1; 1 0 1; 1 1 1; 0 1 1];
Tg = zeros(8, 8);                                % element 1 + i + 2 (j + 2 k), VTK order
for c = 0:7
  ijk = [mod(c, 2), mod(floor(c / 2), 2), floor(c / 4)];
  for v = 1:8
    Tg(v, c + 1) = 1 + [1 3 9] * (ijk + corners(v, :))';
  end
end
Bg = cgcontact_body(Ng, Tg);
P = [0.5 0.5 2.3; 0.5 0.5 1.8; -0.25 1.5 0.5; 2.2 2.2 2.2; 0.5 0.5 3.0]';
[G, C, N, FE, F] = gap(Bg, P, 0.5);
near = @(a, b) all(abs(a(:) - b(:)) < 1e-12);
check(near(G(1:3), [0.3 -0.2 0.25]), 'gaps above, below and beside a face: %s', mat2str(G));
check(near(C(:, 1:3), [0.5 0.5 2; 0.5 0.5 2; 0 1.5 0.5]'), 'closest points: %s', mat2str(C));
check(near(N(:, 1:3), [0 0 1; 0 0 1; -1 0 0]'), 'normals: %s', mat2str(N));
check(isequal(FE(1:3), [5 5 3]) && isequal(F(1:3), [5 5 0]), 'faces: %s %s', mat2str(FE), mat2str(F));
check(near(G(4), 0.2 * sqrt(3)) && near(C(:, 4), [2; 2; 2]) && near(N(:, 4), [1; 1; 1] / sqrt(3)) ...
      && FE(4) == 8, 'the corner (2, 2, 2): %g %s %s %d', G(4), mat2str(C(:, 4)), mat2str(N(:, 4)), FE(4));
check(isnan(G(5)) && all(isnan([C(:, 5); N(:, 5)])) && FE(5) == 0 && F(5) == -1, ...
      'beyond D: %g %d %d', G(5), FE(5), F(5));
check(near(P(:, 1:4), C(:, 1:4) + G(1:4) .* N(:, 1:4)), 'XYZ = C + G .* N');
% Translated by 0.1 up: the point 0.3 above the top is now 0.2 above; the same through the
% wrapper and a plain handle.
update(Bg, repmat([0 0 0.1], 27, 1));
[G2, C2, N2, FE2, F2] = cgcontact_gap(Bg, P(:, 1), 0.5);
check(near(G2, 0.2) && near(C2, [0.5; 0.5; 2.1]) && near(N2, [0; 0; 1]) && FE2 == 5 && F2 == 5, ...
      'translated block: %g %s', G2, mat2str(C2));
check(isequal(cgcontact_gap(Bg.id, P(:, 1), 0.5), G2), 'cgcontact_gap with a handle number');
check(isequal(gap(Bg, zeros(3, 0), 0.5), zeros(1, 0)), 'no points');
expect_error('cgcontact:badInput', @() gap(Bg, P, -1), 'gap with D = -1');
expect_error('cgcontact:badInput', @() gap(Bg, P, NaN), 'gap with D = NaN');
expect_error('cgcontact:badSize', @() gap(Bg, P', 0.5), 'gap with XYZ'' (n x 3)');
expect_error('cgcontact:nonFinitePoint', @() gap(Bg, [P [NaN; 0; 0]], 0.5), 'gap with a NaN point');
clear Bg;
printf('gap: known gaps, closest points, normals and faces on a 2 x 2 x 2 block, translated too\n');

% --- bad input raises errors, never crashes -----------------------------------------------
printf('bad input:\n');
bad = N0; bad(2, 7) = bad(2, 7) + 0.01 * h(2);
nanU = U; nanU(9, 2) = NaN;
nanX = XYZ(:, 1:3); nanX(3, 2) = NaN;
T0 = T; T0(4, 3) = 0;
Tf = T; Tf(1, 1) = 1.5;
Tswap = T; Tswap([1 2], 1) = Tswap([2 1], 1);
expect_error('cgcontact:badSize', @() cgcontact_whereami(XYZ(1:2, :), N0, T, U), 'XYZ 2 x n');
expect_error('cgcontact:badSize', @() cgcontact_whereami(XYZ, N0', T, U), 'XYZ_N0 m x 3');
expect_error('cgcontact:badSize', @() cgcontact_whereami(XYZ, N0, T(1:7, :), U), 'Topology 7 x e');
expect_error('cgcontact:badSize', @() cgcontact_whereami(XYZ, N0, T, U(:, 1:2)), 'U m x 2');
expect_error('cgcontact:badSize', @() cgcontact_whereami(XYZ, N0, T, U(1:end-1, :)), 'U (m-1) x 3');
expect_error('cgcontact:badInput', @() cgcontact_whereami(single(XYZ), N0, T, U), 'XYZ single');
expect_error('cgcontact:badInput', @() cgcontact_whereami(XYZ, N0, Tf, U), 'Topology 1.5');
expect_error('cgcontact:invalidArgument', @() cgcontact_whereami(XYZ, N0, T0, U), 'Topology 0');
expect_error('cgcontact:nonFinitePoint', @() cgcontact_whereami(nanX, N0, T, U), 'XYZ NaN');
expect_error('cgcontact:nonFinite', @() cgcontact_whereami(XYZ, N0, T, nanU), 'U NaN');
expect_error('cgcontact:nonFinite', @() cgcontact_whereami(XYZ, [N0(:, 1:end-1) [Inf; 0; 0]], T, U), 'XYZ_N0 Inf');
expect_error('cgcontact:notLattice', @() cgcontact_whereami(XYZ, bad, T, U), 'a node off the lattice');
expect_error('cgcontact:notLattice', @() cgcontact_whereami(XYZ, N0, Tswap, U), 'corners out of VTK order');
expect_error('cgcontact:badInput', @() cgcontact_whereami(XYZ, N0, T, U, struct('precision', 'f16')), 'Options.precision');
expect_error('cgcontact:invalidArgument', @() cgcontact_whereami(XYZ, N0, T, U, struct('tol', -1)), 'Options.tol');
expect_error('cgcontact:usage', @() cgcontact_whereami(XYZ, N0), 'too few arguments');
expect_error('cgcontact:usage', @() cgcontact_whereami('frobnicate'), 'unknown command');
% A NUL inside the row ended the C string: 'locate' and more was taken for 'locate'.
expect_error('cgcontact:usage', @() cgcontact_whereami(['locate' char(0) 'x'], H, XYZ), 'a command with a NUL inside');
expect_error('cgcontact:badInput', @() cgcontact_whereami(XYZ, N0, T, U, struct('precision', ['f32' char(0)])), 'Options.precision with a NUL');
expect_error('cgcontact:badHandle', @() cgcontact_whereami('locate', 99, XYZ), 'a handle never made');
expect_error('cgcontact:badSize', @() cgcontact_whereami('update', H, U'), 'update with U'' (3 x m)');
expect_error('cgcontact:nonFinitePoint', @() cgcontact_whereami('locate', H, nanX), 'locate NaN');
% Inputs that were ignored or reinterpreted without a word: a misspelt option, an empty U to
% 'update' (it kept the last displacements), fill_hanging = NaN (read as true), a command name
% too long to read (named '' in the message), Repeats as text (its character code).
expect_error('cgcontact:badInput', @() cgcontact_whereami(XYZ, N0, T, U, struct('Precision', 'f32')), 'Options.Precision (misspelt)');
expect_error('cgcontact:badInput', @() cgcontact_whereami(XYZ, N0, T, U, struct('maxiter', 5)), 'Options.maxiter (misspelt)');
expect_error('cgcontact:badInput', @() cgcontact_whereami(XYZ, N0, T, U, struct('fill_hanging', NaN)), 'Options.fill_hanging NaN');
expect_error('cgcontact:badSize', @() cgcontact_whereami('update', H, []), 'update with U = []');
expect_error('cgcontact:badSize', @() cgcontact_whereami(XYZ, N0, T, {}), 'U = {}');
% Options as {} or '' were read as no options: a wrong type, as any other non-struct is.
expect_error('cgcontact:badInput', @() cgcontact_whereami(XYZ, N0, T, U, {}), 'Options = {}');
expect_error('cgcontact:badInput', @() cgcontact_whereami(XYZ, N0, T, U, ''), 'Options = empty text');
expect_error('cgcontact:badInput', @() cgcontact_whereami('new', N0, T, {}), 'new with Options = {}');
[Ee, Pe] = cgcontact_whereami(XYZ, N0, T, U, struct([]));
[En, Pn] = cgcontact_whereami(XYZ, N0, T, U);
check(isequal(Ee, En) && isequaln(Pe, Pn), 'Options = struct([]) answers as no options');

expect_error('cgcontact:usage', @() cgcontact_whereami('locate_every_point_please', H, XYZ), 'a long command');
expect_error('cgcontact:badInput', @() cgcontact_whereami('query_seconds', H, XYZ, 'abc'), 'Repeats as text');
expect_error('cgcontact:badInput', @() cgcontact_whereami('query_seconds', H, XYZ, 2.5), 'Repeats 2.5');
% An N-d array's size was given as mxGetM x mxGetN: a 3 x 1 x 2 XYZ was refused as "3 x 2".
X3 = reshape(XYZ(:, 1:2), 3, 1, 2);
expect_error('cgcontact:badSize', @() cgcontact_whereami('locate', H, X3), 'locate with a 3 x 1 x 2 XYZ', 'got double 3 x 1 x 2');
expect_error('cgcontact:badSize', @() cgcontact_whereami(X3, N0, T, U), 'one-shot with a 3 x 1 x 2 XYZ', 'got 3 x 1 x 2');
expect_error('cgcontact:badSize', @() cgcontact_whereami('relocate', H, XYZ(:, 1:2), [1 1], zeros(3, 1, 2)), ...
             'relocate with a 3 x 1 x 2 PosL0', 'got 3 x 1 x 2');
% Numeric options of an integer class were refused as "not a real scalar": they are numbers.
[Ed, Pd] = cgcontact_whereami(XYZ, N0, T, U, struct('threads', 1, 'max_iter', 40));
[Ei, Pi] = cgcontact_whereami(XYZ, N0, T, U, struct('threads', int32(1), 'max_iter', uint8(40)));
check(isequal(Ed, Ei) && isequaln(Pd, Pi), 'Options of integer classes answer as doubles');
expect_error('cgcontact:badInput', @() cgcontact_whereami(XYZ, N0, T, U, struct('threads', true)), ...
             'Options.threads logical', 'got logical 1 x 1');
% Outputs a command does not give, refused before it runs: asked for an output, 'free' and
% 'update' did their work, then failed with Octave's "element number 1 undefined in return list".
[Ekept, ~] = cgcontact_whereami('locate', H, XYZ);
expect_error('cgcontact:usage', @() ask_outputs(1, 'free', H), 'free with an output');
[Efree, ~] = cgcontact_whereami('locate', H, XYZ);
check(isequal(Efree, Ekept), 'free with an output freed the handle, or changed its answers');
expect_error('cgcontact:usage', @() ask_outputs(1, 'update', H, U), 'update with an output');
expect_error('cgcontact:usage', @() ask_outputs(3, 'locate', H, XYZ), 'locate with 3 outputs');
expect_error('cgcontact:usage', @() ask_outputs(2, 'inverted_cells', H), 'inverted_cells with 2 outputs');
expect_error('cgcontact:usage', @() ask_outputs(4, XYZ, N0, T, U), 'one-shot with 4 outputs');
expect_error('cgcontact:usage', @() cgcontact_whereami('handles', H), 'handles with an argument');
expect_error('cgcontact:usage', @() cgcontact_whereami(repmat('x', 1, 40), H), 'a command of 40 characters');
expect_error('cgcontact:badSize', @() cgcontact_whereami('update', H, sparse(U)), 'update with a sparse U', ...
             sprintf('got sparse double %d x 3', rows(U)));
expect_error('cgcontact:badSize', @() cgcontact_whereami('update', H, complex(U)), 'update with a complex U', ...
             sprintf('got complex double %d x 3', rows(U)));
% A complex or sparse XYZ was described by its class alone: "got double 3 x n".
nX = columns(XYZ);
expect_error('cgcontact:badSize', @() cgcontact_whereami('locate', H, complex(XYZ)), 'locate with a complex XYZ', ...
             sprintf('got complex double 3 x %d', nX));
expect_error('cgcontact:badSize', @() cgcontact_whereami('locate', H, sparse(XYZ)), 'locate with a sparse XYZ', ...
             sprintf('got sparse double 3 x %d', nX));
expect_error('cgcontact:badSize', @() cgcontact_whereami('locate', H, sparse(XYZ + 1i)), ...
             'locate with a sparse complex XYZ', sprintf('got sparse complex double 3 x %d', nX));
[Eh, Ph] = cgcontact_whereami('locate', H, XYZ);
expect_error('cgcontact:badSize', @() cgcontact_whereami('relocate', H, complex(XYZ), Eh, Ph), ...
             'relocate with a complex XYZ', sprintf('got complex double 3 x %d', nX));
expect_error('cgcontact:badInput', @() cgcontact_whereami('relocate', H, XYZ, complex(Eh), Ph), ...
             'relocate with a complex E0', sprintf('got complex double 1 x %d', nX));
expect_error('cgcontact:badInput', @() cgcontact_whereami('relocate', H, XYZ, Eh, sparse(Ph)), ...
             'relocate with a sparse PosL0', sprintf('got sparse double 3 x %d', nX));
expect_error('cgcontact:badInput', @() cgcontact_whereami(complex(XYZ), N0, T, U), 'one-shot with a complex XYZ', ...
             sprintf('got complex double 3 x %d', nX));
expect_error('cgcontact:badInput', @() cgcontact_whereami('gap', H, sparse(XYZ), 0.5), 'gap with a sparse XYZ', ...
             sprintf('got sparse double 3 x %d', nX));
try
  cgcontact_whereami('locate_every_point_please', H, XYZ);
catch err
  check(isempty(strfind(err.message, "''")), 'a long command named as empty: %s', err.message);
end
cgcontact_whereami('free', H);
expect_error('cgcontact:badHandle', @() cgcontact_whereami('locate', H, XYZ), 'a freed handle');
expect_error('cgcontact:badHandle', @() cgcontact_whereami('inverted_cells', H), 'inverted_cells, a freed handle');
check(cgcontact_whereami('handles') == 0, 'no live handle');
% A freed handle stays freed when its slot is given again: it answered for the new body before.
Hnext = cgcontact_whereami('new', N0, T);
check(Hnext ~= H, 'a freed handle''s number given again (%g)', Hnext);
expect_error('cgcontact:badHandle', @() cgcontact_whereami('locate', H, XYZ), 'a freed handle, its slot given again');
[E2, PosL2] = cgcontact_whereami('locate', Hnext, XYZ);
[E1, PosL1] = cgcontact_whereami(XYZ, N0, T, []);
check(isequal(E2, E1) && isequaln(PosL2, PosL1), 'the new handle answers as its body');
cgcontact_whereami('free', Hnext);
check(cgcontact_whereami('handles') == 0, 'no live handle');
% Still working after all those errors, and after `clear all` (the MEX file stays loaded).
clear all;
[E, PosL] = cgcontact_whereami([0.5; 0.5; 0.5], [0 1 1 0 0 1 1 0; 0 0 1 1 0 0 1 1; 0 0 0 0 1 1 1 1], (1:8)', zeros(8, 3));
if ~(E == 1 && max(abs(PosL)) < 1e-15)
  fprintf(2, 'FAILED: the unit cube after clear all\n');
  exit(1);
end
printf('octave: all cgcontact_whereami checks passed\n');
