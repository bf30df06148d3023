% [G, C, N, FE, F] = cgcontact_gap(H, XYZ, D): signed gaps of the points XYZ (3 x n) to the deformed
% boundary surface of a body, searched within the distance D (finite, >= 0).
%
%   H   a handle from cgcontact_whereami('new', ...), or a cgcontact_body
%   G   1 x n  distance to the closest surface point, negative inside the body
%   C   3 x n  that closest point
%   N   3 x n  unit outward normal there: XYZ = C + G .* N (to 2 |G| within the locator's
%              rounding allowance of the surface, where N is then the face's normal)
%   FE  1 x n  1-based element whose face holds C (0 when none)
%   F   1 x n  its local face, 0..5: face f at local coordinate f/2 (xi, eta, zeta) = -1 for even
%              f, +1 for odd f (5 is the top, zeta = +1); -1 when none
%
% G, C and N are NaN, FE 0 and F -1 where the surface is farther than D. The same as
% cgcontact_whereami('gap', H, XYZ, D); build.sh puts this file beside the MEX file.
function [G, C, N, FE, F] = cgcontact_gap(H, XYZ, D)
  if isa(H, 'cgcontact_body')
    H = H.id;
  end
  [G, C, N, FE, F] = cgcontact_whereami('gap', H, XYZ, D);
end
