% B = cgcontact_body(XYZ_N0, Topology [, Options]): a deformable body and its locator for solver
% loops, freed automatically when B is cleared or goes out of scope.
%
%   B = cgcontact_body(XYZ_N0, Topology);   % 3 x m nodes, 8 x e 1-based topology (VTK order)
%   update(B, U);                           % m x 3 displacements, each iteration
%   [E, PosL] = locate(B, XYZ);             % as cgcontact_whereami(XYZ, XYZ_N0, Topology, U)
%   [E, PosL] = relocate(B, XYZ, E, PosL);  % the next iteration, warm started from the last answers
%   [G, C, N, FE, F] = gap(B, XYZ, D);      % gaps to the surface within D (cgcontact_whereami 'gap')
%   Inverted = inverted_cells(B);           % 1-based elements U inverts (det J <= 0 at a corner)
%   Unresolved = unresolved_cells(B);       % 1-based elements f64 cannot resolve (see the MEX)
%
% A handle object over cgcontact_whereami's 'new', 'update', 'locate', 'relocate', 'gap',
% 'inverted_cells', 'unresolved_cells' and 'free' (build.sh puts it beside cgcontact_whereami.mex). Options as for cgcontact_whereami.
classdef cgcontact_body < handle
  properties (SetAccess = private)
    % The cgcontact_whereami handle (0 when none).
    id = 0;
  end
  methods
    function obj = cgcontact_body(XYZ_N0, Topology, varargin)
      obj.id = cgcontact_whereami('new', XYZ_N0, Topology, varargin{:});
    end
    function update(obj, U)
      cgcontact_whereami('update', obj.id, U);
    end
    function [E, PosL] = locate(obj, XYZ)
      [E, PosL] = cgcontact_whereami('locate', obj.id, XYZ);
    end
    function [E, PosL] = relocate(obj, XYZ, E0, PosL0)
      [E, PosL] = cgcontact_whereami('relocate', obj.id, XYZ, E0, PosL0);
    end
    function [G, C, N, FE, F] = gap(obj, XYZ, D)
      [G, C, N, FE, F] = cgcontact_whereami('gap', obj.id, XYZ, D);
    end
    function Inverted = inverted_cells(obj)
      Inverted = cgcontact_whereami('inverted_cells', obj.id);
    end
    function Unresolved = unresolved_cells(obj)
      Unresolved = cgcontact_whereami('unresolved_cells', obj.id);
    end
    function delete(obj)
      if obj.id > 0
        try
          cgcontact_whereami('free', obj.id);   % already freed if Octave is exiting
        catch
        end
        obj.id = 0;
      end
    end
  end
end
