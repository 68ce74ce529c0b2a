function x = sbatest_focal_proj(j, i, aj, bi, varargin)
% SBATEST_FOCAL_PROJ  A pinhole camera with a focal length of its own: aj = [w t f], w the
% rotation as an axis times its angle, t the translation; bi the 3D point. Extra arguments
% are ignored (test_camera_params passes a struct of problem data through).
  X = sbatest_rotation(aj(1:3)) * bi(:) + reshape(aj(4:6), 3, 1);
  x = aj(7) * [X(1) X(2)] / X(3);
end
% SPDX-License-Identifier: BSD-3-Clause
