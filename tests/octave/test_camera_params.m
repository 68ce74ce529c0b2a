function test_camera_params()
% The options struct (beyond 1.6): camera parameters held (fixed_params) and shared by groups
% of cameras (camera_groups, shared_params), on a synthetic scene of 6 cameras whose focal
% lengths start 2% long (SBATEST_FOCAL_SCENE, SBATEST_FOCAL_PROJ, finite-difference Jacobians).
  s = sbatest_focal_scene(800 * ones(1, 6));
  f = 7 * (0:s.m - 1) + 7;                    % the focal lengths in p0
  % Camera 0's pose and camera 1's x translation held: that fixes the gauge (7 degrees).
  held = false(s.m, 7);
  held(1, 1:6) = true;
  held(2, 4) = true;
  hidx = find(held');                         % their places in p0
  one = struct('fixed_params', held, 'camera_groups', zeros(1, s.m), ...
               'shared_params', [0 0 0 0 0 0 1]);

  % One focal length for the six cameras: it comes back to the truth, every camera with the
  % same bits, and the held parameters keep theirs.
  [ret, p, info] = run_scene(s, 'motstr', one);
  printf('one shared focal length: %.6f (truth 800, start 816), %d iterations, error %.9g\n', ...
         p(f(1)), ret, info(2));
  sbatest_assert(ret >= 15 && ret <= 25, 'shared focal length: %d iterations', ret);
  sbatest_assert(all(p(f) == p(f(1))), 'the cameras of the group end with different focal lengths');
  sbatest_assert(abs(p(f(1)) - 799.805372) < 1e-4 && abs(info(2) - 20.4649433) < 1e-6 * 20.5, ...
                 'shared focal length %.6f, error %.9g', p(f(1)), info(2));
  sbatest_assert(isequal(p(hidx), s.p0(hidx)), 'a held parameter moved');
  sbatest_assert(any(p(setdiff(1:42, [hidx; f'])) ~= s.p0(setdiff(1:42, [hidx; f'])) ), ...
                 'the free camera parameters did not move');

  % Without the struct each camera gets a focal length of its own (the fit is closer, the
  % focal lengths spread); fixed_params alone holds without sharing.
  [ret0, p0, info0] = run_scene(s, 'motstr');
  printf('no struct: focal lengths %.3f .. %.3f, error %.9g\n', min(p0(f)), max(p0(f)), info0(2));
  sbatest_assert(ret0 > 0 && max(p0(f)) - min(p0(f)) > 0.01 && info0(2) < info(2), ...
                 'without camera_groups the focal lengths are %.6f .. %.6f, error %.9g', ...
                 min(p0(f)), max(p0(f)), info0(2));
  [rh, ph] = run_scene(s, 'motstr', struct('fixed_params', held));
  sbatest_assert(rh > 0 && isequal(ph(hidx), s.p0(hidx)) && max(ph(f)) - min(ph(f)) > 0.01, ...
                 'fixed_params alone');

  % Before or after reftype, with 'strategy=NAME' on either side: the same call.
  [ret2, p2, info2] = run_scene(s, one, 'motstr');
  sbatest_assert(ret2 == ret && isequal(p2, p) && isequal(info2, info), ...
                 'the struct before reftype gives another result');
  [rt, pt, it] = run_scene(s, one, 'strategy=trust-region', 'motstr');
  [rt2, pt2] = run_scene(s, 'motstr', 'strategy=trust-region', one);
  printf('trust-region: %.6f in %d iterations, error %.9g\n', pt(f(1)), rt, it(2));
  sbatest_assert(rt >= 3 && rt <= 6 && rt2 == rt && isequal(pt2, pt), 'the struct beside strategy=');
  sbatest_assert(all(pt(f) == pt(f(1))) && abs(pt(f(1)) - p(f(1))) < 1e-3 && ...
                 abs(it(2) - info(2)) <= 1e-6 * info(2), ...
                 'trust-region ends at %.9g (f %.6f), sba at %.9g (f %.6f)', it(2), pt(f(1)), ...
                 info(2), p(f(1)));

  % Two groups and a camera in none, each with its own true focal length; group numbers need
  % not be contiguous.
  s2 = sbatest_focal_scene([800 800 800 900 900 850]);
  two = one;
  two.camera_groups = [0 0 0 3 3 -1];
  [ret, p, info] = run_scene(s2, 'motstr', two);
  param_groups_as_camera_groups(s2, two, ret, p, info);
  printf('two groups: %.6f, %.6f and %.6f alone (truths 800, 900, 850)\n', p(f(1)), p(f(4)), p(f(6)));
  sbatest_assert(ret > 0 && all(p(f(1:3)) == p(f(1))) && all(p(f(4:5)) == p(f(4))), ...
                 'two groups: the focal lengths within a group differ');
  sbatest_assert(all(abs(p(f([1 4 6])) - [799.948887 900.079503 849.266764]) < 1e-4), ...
                 'two groups: %.6f %.6f %.6f', ...
                 p(f(1)), p(f(4)), p(f(6)));

  % Motion only: the points keep p0's values, the shared focal length is still one.
  [ret, p] = run_scene(s, 'mot', one);
  sbatest_assert(ret > 0 && all(p(f) == p(f(1))) && isequal(p(43:end), s.p0(43:end)) && ...
                 isequal(p(hidx), s.p0(hidx)), 'motion only');

  % A struct with none of the three fields is problem data, as in sba 1.6: passed to an
  % interpreted projection (NAME@LIBRARY takes double arrays only), which ignores it. Three
  % iterations tell: each is a dozen interpreted calls per observation.
  sm = s;
  sm.proj = 'sbatest_focal_proj';
  short = scene_args(sm);
  short{13} = 3;                              % itmax
  [retm, pm] = sba(short{:}, 'motstr');
  [ret, p] = sba(short{:}, 'motstr', struct('foo', 1));
  sbatest_assert(retm == 3 && ret == retm && isequal(p, pm), 'a struct of other fields is not problem data');
  [ret, p] = sba(short{:}, 'motstr', struct('foo', {1, 2}));
  sbatest_assert(ret == retm && isequal(p, pm), 'a struct array of other fields is not problem data');

  % Bad structs: an error naming the field, or the solver's refusal naming the camera.
  part = held;
  part(3, 7) = true;                          % held in one camera of the group only
  cases = {
    struct('fixed_params', true(1, 5)), 'sba:wrongSize', ...
      'fixed_params must have cnp = 7 flags \(for every camera\) or be m x cnp = 6 x 7 \(got 1 x 5\)'
    struct('fixed_params', [0 0 0 NaN 0 0 0]), 'sba:invalidArgument', 'fixed_params\(4\) is not finite'
    struct('fixed_params', {{1}}), 'sba:invalidArgument', 'fixed_params must be a dense real or logical matrix'
    struct('fixed_params', with(double(held), 2, 4, NaN)), 'sba:invalidArgument', ...
      'fixed_params\(2,4\) is not finite\.$'
    struct('camera_groups', zeros(1, 6)), 'sba:invalidProblem', 'cam_group is given but cam_shared is NULL$'
    struct('shared_params', ones(1, 7)), 'sba:invalidProblem', 'cam_shared is given but cam_group is NULL$'
    setfield(one, 'camera_groups', [0 0 0 0 0 6]), 'sba:invalidProblem', ...
      'cam_group\[5\] = 6 is neither -1 nor a group number in \[0, m-1\]$'
    setfield(one, 'camera_groups', [0 -2 0 0 0 0]), 'sba:invalidProblem', ...
      'cam_group\[1\] = -2 is neither -1 nor a group number in \[0, m-1\]$'
    setfield(one, 'camera_groups', [0 0.5 0 0 0 0]), 'sba:invalidArgument', ...
      'camera_groups\(2\) must be a whole number within \[-2147483648, 2147483647\] \(got 0.5\)\.$'
    setfield(one, 'camera_groups', zeros(1, 5)), 'sba:wrongSize', 'camera_groups must have m = 6 values \(got 5\)'
    setfield(one, 'camera_groups', false(1, 6)), 'sba:invalidArgument', ...
      'camera_groups must be a dense real numeric matrix of group numbers \(got a 1x6 logical\)\.$'
    setfield(one, 'shared_params', [0 1]), 'sba:wrongSize', 'shared_params must have cnp = 7 flags \(got 2\)'
    setfield(one, 'camera_group', 1), 'sba:invalidArgument', ...
      'the options struct has an unknown field ''camera_group'''
    setfield(one, 'fixed_params', part), 'sba:invalidProblem', 'shared by cameras 0 and 2 .*held'
    [one, one], 'sba:invalidArgument', ...
      'the options struct must be a 1x1 struct \(got a 1x2 struct array\)\.$'
    struct('fixed_params', {}), 'sba:invalidArgument', ...
      'the options struct must be a 1x1 struct \(got a 0x0 struct array\)\.$'
  };
  base = scene_args(s);
  for c = 1:size(cases, 1)
    sbatest_expect_error([base, {'motstr', cases{c, 1}}], cases{c, 2}, cases{c, 3});
  end
  sbatest_expect_error([base, {'str', one}], 'sba:invalidArgument', 'reftype ''str'' does not refine');
  base{4} = 1;                                % mcon 1: camera 0 cannot be in a group
  sbatest_expect_error([base, {'motstr', one}], 'sba:invalidProblem', 'camera 0 is below mcon');
  printf('%d bad structs refused\n', size(cases, 1) + 2);
  param_groups_of_a_rig();
  bad_param_groups(s);
end

% param_groups (m x cnp, row j camera j-1's numbers) holding what the struct `groups` says
% with camera_groups and shared_params, of another numeric class: the same solve, bit for bit.
% Rows and columns matter: the groups differ from camera to camera, not the parameters.
function param_groups_as_camera_groups(s, groups, ret, p, info)
  pg = -ones(s.m, s.cnp);
  pg(:, logical(groups.shared_params)) = repmat(groups.camera_groups', 1, nnz(groups.shared_params));
  [ret1, p1, info1] = run_scene(s, 'motstr', struct('fixed_params', groups.fixed_params, ...
                                                      'param_groups', int32(pg)));
  sbatest_assert(ret1 == ret && isequal(p1, p) && isequal(info1, info), ...
                 'param_groups as camera_groups: %d iterations (%d), error %.9g (%.9g)', ret1, ret, ...
                 info1(2), info(2));
end

% A stereo rig over three places: the rotation shared by the two cameras of a place, the focal
% length by all six, the translations their own. Nothing holds the gauge, and the scale of
% the scene (with it the focal length) is barely observed: sba's default stop (eps4 = 0, the
% relative reduction lost in rounding) ends the run somewhere along that valley, after 19 to 38
% iterations as the BLAS rounds, within 1e-5 of its floor. The floor itself is the problem's:
% a trust-region run to a relative cost change of 1e-14 reaches it.
function param_groups_of_a_rig()
  s = sbatest_focal_scene(800 * ones(1, 6), true);
  f = 7 * (0:s.m - 1) + 7;
  pg = -ones(s.m, 7);
  pg(:, 1:3) = repmat(floor((0:s.m - 1)' / 2), 1, 3);
  pg(:, 7) = 0;
  [ret, p, info] = run_scene(s, 'motstr', struct('param_groups', pg));
  a = reshape(p(1:7 * s.m), 7, s.m);              % column j: camera j-1's parameters
  printf('a rig: focal length %.6f (truth 800, start 816), %d iterations, error %.9g\n', ...
         p(f(1)), ret, info(2));
  sbatest_assert(ret > 0 && all(p(f) == p(f(1))) && isequal(a(1:3, 1:2:end), a(1:3, 2:2:end)), ...
                 'a rig: the copies of a shared parameter differ');
  sbatest_assert(numel(unique(a(1, 1:2:end))) == 3 && numel(unique(a(4, :))) == 6, ...
                 'a rig: parameters shared that were not to be');
  floor_error = 20.98777061;                      % and a focal length of 800.014446
  sbatest_assert(info(2) >= floor_error * (1 - 1e-9) && info(2) <= floor_error * (1 + 1e-5) && ...
                 abs(p(f(1)) - 800.014446) < 0.2, 'a rig: focal length %.6f, error %.9g', p(f(1)), info(2));
  tight = scene_args(s);
  tight{15} = [1e-3 1e-30 1e-30 1e-30 1e-14];                 % opts
  [rt, pt, it] = sba(tight{:}, 'motstr', 'strategy=trust-region', struct('param_groups', pg));
  printf('a rig, converged: focal length %.6f, %d iterations, error %.10g\n', pt(f(1)), rt, it(2));
  sbatest_assert(rt > 0 && abs(it(2) - floor_error) < 1e-9 * floor_error && abs(pt(f(1)) - 800.014446) < 1e-3, ...
                 'a rig, converged: focal length %.6f, error %.10g', pt(f(1)), it(2));
  % One grouping for both (every camera sharing the rotation and the focal length) turns the
  % three places alike: a far worse fit, whose end moves with the BLAS's rounding by a few parts
  % in 1e7.
  [ret1, ~, info1] = run_scene(s, 'motstr', struct('camera_groups', zeros(1, s.m), ...
                                                    'shared_params', [1 1 1 0 0 0 1]));
  printf('a rig as one group: error %.9g\n', info1(2));
  sbatest_assert(ret1 > 0 && abs(info1(2) - 215304.388) < 1e-5 * 215304, ...
                 'a rig as one group: error %.9g', info1(2));
end

% Bad param_groups: an error naming the field where it is not an int array of m x cnp, else
% the library's refusal.
function bad_param_groups(s)
  pg = -ones(s.m, 7);
  pg(:, 7) = 0;                               % one focal length
  pairs = pg;
  pairs(:, 1:3) = repmat(floor((0:s.m - 1)' / 2), 1, 3);
  range = 'must be a whole number within \[-2147483648, 2147483647\]';
  cases = {
    struct('param_groups', zeros(6, 6)), 'sba:wrongSize', ...
      'param_groups must be m x cnp = 6 x 7 \(got 6 x 6\)\.$'
    struct('param_groups', pg'), 'sba:wrongSize', 'param_groups must be m x cnp = 6 x 7 \(got 7 x 6\)\.$'
    struct('param_groups', with(pg, 2, 3, 0.5)), 'sba:invalidArgument', ...
      ['param_groups\(2,3\) ', range, ' \(got 0.5\)\.$']
    struct('param_groups', with(pg, 6, 1, -2)), 'sba:invalidProblem', ...
      'cam_param_group\[35\] = -2 is neither -1 nor a group number >= 0$'
    struct('param_groups', with(pg, 6, 1, -2^31 - 1)), 'sba:invalidArgument', ...
      ['param_groups\(6,1\) ', range, ' \(got -2147483649\)\.$']
    struct('param_groups', with(pg, 1, 7, 2^31)), 'sba:invalidArgument', ...
      ['param_groups\(1,7\) ', range, ' \(got 2147483648\)\.$']
    struct('param_groups', with(pg, 3, 2, NaN)), 'sba:invalidArgument', 'param_groups\(3,2\) is not finite\.$'
    struct('param_groups', {{pg}}), 'sba:invalidArgument', ...
      'param_groups must be a dense real numeric matrix of group numbers \(got a 1x1 cell\)\.$'
    struct('param_groups', pg >= 0), 'sba:invalidArgument', ...
      'param_groups must be a dense real numeric matrix of group numbers \(got a 6x7 logical\)\.$'
    setfield(struct('param_groups', pg), 'camera_group', 1), 'sba:invalidArgument', ...
      ['unknown field ''camera_group'' \(expected fixed_params, camera_groups, shared_params, ', ...
       'param_groups, point_priors, camera_linear_priors or camera_priors\)\.$']
    struct('param_groups', pg, 'camera_groups', zeros(1, 6), 'shared_params', [0 0 0 0 0 0 1]), ...
      'sba:invalidProblem', 'cam_param_group and cam_group/cam_shared are given together: give one of the two'
    struct('param_groups', pairs, 'fixed_params', with(false(6, 7), 1, 1, true)), 'sba:invalidProblem', ...
      ['parameter 0 is shared by cameras 0 and 1 \(cam_param_group 0\) but held \(cam_fixed\) in ', ...
       'only one of them']
  };
  base = scene_args(s);
  for c = 1:size(cases, 1)
    sbatest_expect_error([base, {'motstr', cases{c, 1}}], cases{c, 2}, cases{c, 3});
  end
  sbatest_expect_error([base, {'str', struct('param_groups', pg)}], 'sba:invalidArgument', ...
                       'param_groups apply to cameras, which reftype ''str'' does not refine');
  base{4} = 1;                                % mcon 1: camera 0 shares nothing
  sbatest_expect_error([base, {'mot', struct('param_groups', pg)}], 'sba:invalidProblem', ...
                       ['cam_param_group\[6\] = 0: camera 0 is below mcon = 1 \(held whole\) and ', ...
                        'shares nothing']);
  printf('%d bad param_groups refused\n', size(cases, 1) + 2);
end

function a = with(a, i, j, v)
  a(i, j) = v;
end

function varargout = run_scene(s, varargin)
  args = scene_args(s);
  [varargout{1:nargout}] = sba(args{:}, varargin{:});
end

% sba's arguments up to opts for the scene s: finite-difference Jacobians, 100 iterations.
function args = scene_args(s)
  args = {s.n, 0, s.m, 0, s.vmask, s.p0, s.cnp, s.pnp, s.x, s.mnp, s.proj, '', ...
          100, 0, []};
end
% SPDX-License-Identifier: BSD-3-Clause
