function s = sbatest_focal_scene(focals, rig)
% SBATEST_FOCAL_SCENE  A synthetic scene for SBATEST_FOCAL_PROJ: numel(focals) cameras on an
% arc 8 units from 40 points in a 4 x 4 x 2 box, every point seen by every camera, the
% projections with the true focal lengths FOCALS plus deterministic noise of 0.3 px at most.
% p0 starts every camera at 1.02 times its focal length, the points 0.01 off.
% SBATEST_FOCAL_SCENE(FOCALS, true): a stereo rig instead, cameras 2k-1 and 2k taken at one
% place of the arc, turned alike, the second 0.5 units to the side of the first.
  m = numel(focals);
  n = 40;
  k = (1:n)';
  pts = [2 * sin(1.3 * k), 2 * cos(0.7 * k), sin(2.1 * k)];
  cams = zeros(m, 7);
  for j = 1:m
    k = j;                                      % the place on the arc
    if nargin > 1 && rig
      k = 2 * ceil(j / 2) - 1;
    end
    a = 0.25 * (k - (m + 1) / 2);               % around the y axis, towards the box
    w = [0.02 * sin(k), a, 0.01 * cos(k)];
    C = [8 * sin(a), 0.2 * k, -8 * cos(a)];     % the camera centre
    R = sbatest_rotation(w);
    t = -(R * C')';
    if k ~= j
      t(1) = t(1) - 0.5;
    end
    cams(j, :) = [w, t, focals(j)];
  end
  x = zeros(1, 2 * n * m);
  for i = 1:n
    for j = 1:m
      q = 2 * ((i - 1) * m + j) - 1;
      x(q:q + 1) = sbatest_focal_proj(j - 1, i - 1, cams(j, :), pts(i, :)) + ...
                   0.3 * sin([1.7 2.3] * (q + 3));
    end
  end
  start = cams;
  start(:, 7) = 1.02 * start(:, 7);
  % The solves project through the same formula in C (the interpreter's calls would be most
  % of their time); a test that wants the .m route sets s.proj = 'sbatest_focal_proj'.
  s = struct('n', n, 'm', m, 'cnp', 7, 'pnp', 3, 'mnp', 2, 'vmask', ones(n, m), 'x', x, ...
             'proj', ['sbatest_focal_proj@' sbatest_lib('focal')], ...
             'truth', [reshape(cams', 1, []), reshape(pts', 1, [])], ...
             'p0', [reshape(start', 1, []), reshape((pts + 0.01 * cos(3 * pts))', 1, [])]);
end
% SPDX-License-Identifier: BSD-3-Clause
