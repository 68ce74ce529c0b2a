function test_priors()
% Priors in the options struct (beyond 1.6): point_priors, camera_linear_priors and
% camera_priors, struct arrays with 1-based indices, on the synthetic scene of
% SBATEST_FOCAL_SCENE (6 cameras whose focal lengths start 2% long, finite-difference
% Jacobians). Camera 1 is held (mcon = 1), which fixes the gauge but for the scale.
  s = sbatest_focal_scene(800 * ones(1, 6));
  [ret0, p0, info0] = run_scene(s, 'motstr');
  sbatest_assert(ret0 > 0, 'no priors: ret %d', ret0);

  % Empty prior fields, or empty struct arrays, are no priors: the same bits.
  none = struct('point_priors', [], 'camera_linear_priors', struct('camera', {}, 'params', {}, 'mean', {}), ...
                'camera_priors', []);
  [ret, p, info] = run_scene(s, 'motstr', none);
  sbatest_assert(ret == ret0 && isequal(p, p0) && isequal(info, info0), 'empty prior fields change the solve');

  point_prior_pins(s, p0);
  robust_point_prior(s, p0);
  linear_prior_pulls(s, p0);
  callback_priors(s);
  bad_priors(s);
end

% A point prior of sigma 1e-6 on point 5, 0.05 away from where the solve puts it without:
% the point ends within sigma of the mean (it moves by sigma^2 times the projections'
% gradient there, a few pixels times f / 8 per camera: about 1e-8), and the prior's fit costs
% the projections something.
function point_prior_pins(s, p0)
  b = 42 + (3 * 4 + 1:3 * 4 + 3);             % point 5 in p
  mean = p0(b) + [0.05 -0.03 0.02];
  pp = struct('point', 5, 'mean', mean, 'sigma', 1e-6 * [1 1 1]);
  [ret, p, info] = run_scene(s, 'motstr', struct('point_priors', pp));
  printf('point prior: point 5 %.3g from the mean, error %.9g (%.9g without)\n', max(abs(p(b) - mean)), ...
         info(2), run_error(s, p0));
  sbatest_assert(ret > 0 && max(abs(p(b) - mean)) < 1e-6, 'point prior: point 5 is %.3g from its mean', ...
                 max(abs(p(b) - mean)));
  sbatest_assert(max(abs(p0(b) - mean)) > 0.01, 'the test point starts at its mean');
  sbatest_assert(run_error(s, p) > run_error(s, p0) * (1 + 1e-6), 'pinning point 5 cost the projections nothing');
  % The covariance and sqrt_info forms of the same weight (sqrt_info = 1/sigma on the
  % diagonal): the same problem, the same end within the solve's tolerance.
  pc = pp;
  pc.sigma = [];
  pc.covariance = 1e-12 * eye(3);
  [~, pcov] = run_scene(s, 'motstr', struct('point_priors', pc));
  pc.covariance = [];
  pc.sqrt_info = 1e6 * eye(3);
  [~, psq] = run_scene(s, 'motstr', struct('point_priors', pc));
  sbatest_assert(max(abs(pcov - p)) < 1e-6 && max(abs(psq - p)) < 1e-6, ...
                 'covariance / sqrt_info give another end than sigma: %.3g, %.3g', max(abs(pcov - p)), ...
                 max(abs(psq - p)));
  % A covariance that is not diagonal: column-major in, row-major to the library. The
  % transpose of a symmetric matrix is itself, so an upper-triangular sqrt_info tells: its
  % transpose is lower triangular, which the library refuses.
  L = 1e6 * [1 0.5 0; 0 1 0.5; 0 0 1];
  pc.sqrt_info = L;
  [ret, psq] = run_scene(s, 'motstr', struct('point_priors', pc));
  sbatest_assert(ret > 0 && max(abs(psq(b) - mean)) < 1e-5, 'an upper-triangular sqrt_info: %.3g from the mean', ...
                 max(abs(psq(b) - mean)));
end

% A point prior 50 sigma off (sigma 1e-3, the mean 0.05 away): plain, it pulls the point to
% the mean; a Cauchy loss of scale 1 drops most of the pull of such an outlier (the loss's
% weight at 50 sigma is 1 / (1 + 2500): the point stays 0.037 away); with a scale of 1e4 the
% same loss is quadratic there and pulls as the plain prior does. And in 'str', the cameras
% held, the plain prior's point ends between its start and the mean.
function robust_point_prior(s, p0)
  b = 42 + (3 * 4 + 1:3 * 4 + 3);
  mean = p0(b) + [0.05 0 0];
  pp = struct('point', 5, 'mean', mean, 'sigma', 1e-3 * [1 1 1], 'loss', '', 'loss_scale', []);
  [~, pl] = run_scene(s, 'motstr', struct('point_priors', pp));
  pp.loss = 'cauchy';
  pp.loss_scale = 1;
  [ret, pc] = run_scene(s, 'motstr', struct('point_priors', pp));
  pp.loss_scale = 1e4;
  [~, pw] = run_scene(s, 'motstr', struct('point_priors', pp));
  printf('a point prior 50 sigma off: %.3g from the mean plain, %.3g with cauchy, %.3g with scale 1e4\n', ...
         norm(pl(b) - mean), norm(pc(b) - mean), norm(pw(b) - mean));
  sbatest_assert(ret > 0 && norm(pl(b) - mean) < 0.01 && norm(pc(b) - mean) > 0.03 && ...
                 norm(pw(b) - pl(b)) < 1e-3, 'robust point prior: plain %.3g, cauchy %.3g, scale 1e4 %.3g', ...
                 norm(pl(b) - mean), norm(pc(b) - mean), norm(pw(b) - mean));
  pp = struct('point', 5, 'mean', mean, 'sigma', 1e-3 * [1 1 1]);
  [ret, ps] = run_scene(s, 'str', struct('point_priors', pp));
  d = norm(ps(b) - mean);
  sbatest_assert(ret > 0 && d > 1e-4 && d < 0.05 && isequal(ps(1:42), s.p0(1:42)), ...
                 'a point prior in ''str'': %.3g from the mean', d);
end

% A linear prior on camera 2's focal length (parameter 7), 10 px below where the solve puts
% it, sigma 0.01: the focal length ends at the mean plus sigma^2 / 2 times minus the
% projections' gradient there, checked by central differences of the projections' cost.
function linear_prior_pulls(s, p0)
  fmean = round(p0(14)) - 10;
  lp = struct('camera', 2, 'params', 7, 'mean', fmean, 'sigma', 0.01);
  [ret, p, info] = run_scene(s, 'motstr', struct('camera_linear_priors', lp));
  h = 1e-3;
  e = zeros(size(p));
  e(14) = h;
  g = (run_error(s, p + e) - run_error(s, p - e)) / (2 * h);
  printf('linear prior: f2 %.9f (mean %g, %.6f without), projections'' gradient %.6g\n', p(14), fmean, ...
         p0(14), g);
  sbatest_assert(ret > 0 && abs(p(14) - fmean) < 1e-3 && abs(p0(14) - fmean) > 5, ...
                 'linear prior: f2 %.9f, mean %g', p(14), fmean);
  % Stationarity: 2 (f - mean) / sigma^2 + dE/df = 0.
  sbatest_assert(abs(2 * (p(14) - fmean) / 1e-4 + g) < 1e-3 * abs(g) && abs(g) > 1e-3, ...
                 'linear prior: the prior''s pull %.6g against the projections'' %.6g', ...
                 2 * (p(14) - fmean) / 1e-4, g);
  sbatest_assert(info(2) > run_error(s, p) * (1 + 1e-9), 'info(2) %.9g does not include the prior''s cost', info(2));
  % Two parameters at once with a full covariance, and the prior on a camera in 'mot'.
  lp.covariance = [];                         % [] in an element: not given
  lp2 = lp;
  lp2.camera = 3;
  lp2.params = [7 4];
  lp2.mean = [fmean, p0(18)];
  lp2.sigma = [];
  lp2.covariance = [1e-4 0; 0 1e-4];
  [ret, p] = run_scene(s, 'motstr', struct('camera_linear_priors', [lp, lp2]));
  sbatest_assert(ret > 0 && abs(p(14) - fmean) < 1e-3 && abs(p(21) - fmean) < 1e-3, ...
                 'two linear priors: f2 %.6f, f3 %.6f (mean %g)', p(14), p(21), fmean);
  [ret, p] = run_scene(s, 'mot', struct('camera_linear_priors', lp));
  sbatest_assert(ret > 0 && abs(p(14) - fmean) < 1e-3 && isequal(p(43:end), s.p0(43:end)), ...
                 'a linear prior in ''mot'': f2 %.6f', p(14));
end

% Callback priors: r = func(j, aj, extra...) with j the prior's 1-based camera. The focal
% length's prior written as one is the linear prior's problem: the same end, with a
% function handle, a function name, with jac and without.
function callback_priors(s)
  fmean = 790;
  lin = struct('camera', 2, 'params', 7, 'mean', fmean, 'sigma', 0.01);
  [~, pl, il] = run_scene(s, 'motstr', struct('camera_linear_priors', lin));
  extra = [0 fmean 0 0 0 0];                  % indexed by j: 1-based, or 0
  func = @(j, a, e) a(7) - e(j);
  cp = struct('camera', 2, 'dim', 1, 'func', func, 'sigma', 0.01);
  [ret, p, info] = run_scene(s, 'motstr', struct('camera_priors', cp), extra);
  printf('callback prior: f2 %.9f, error %.9g (the linear prior: %.9f, %.9g)\n', p(14), info(2), pl(14), il(2));
  sbatest_assert(ret > 0 && abs(p(14) - pl(14)) < 1e-6 && abs(info(2) - il(2)) < 1e-8 * il(2), ...
                 'callback prior by handle: f2 %.9f, error %.9g', p(14), info(2));
  cp.jac = @(j, a, e) [0 0 0 0 0 0 1];
  [ret, p] = run_scene(s, 'motstr', struct('camera_priors', cp), extra);
  sbatest_assert(ret > 0 && abs(p(14) - pl(14)) < 1e-6, 'callback prior with jac: f2 %.9f', p(14));
  cp.func = 'sbatest_prior_focal';
  cp.jac = '';
  [ret, p] = run_scene(s, 'motstr', struct('camera_priors', cp), extra);
  sbatest_assert(ret > 0 && abs(p(14) - pl(14)) < 1e-6, 'callback prior by name: f2 %.9f', p(14));
end

function bad_priors(s)
  pp = struct('point', 5, 'mean', [1 2 3], 'sigma', [1 1 1]);
  lp = struct('camera', 2, 'params', 7, 'mean', 790, 'sigma', 0.01);
  cp = struct('camera', 2, 'dim', 1, 'func', @(j, a) a(7) - 790, 'sigma', 0.01);
  one = 'must be a whole number within \[1, 2147483647\], a 1-based index';
  cases = {
    struct('point_priors', {{pp}}), 'sba:invalidArgument', ...
      'point_priors must be a struct array, one element per prior \(got a 1x1 cell\)\.$'
    struct('point_priors', setfield(pp, 'sigmas', 1)), 'sba:invalidArgument', ...
      ['point_priors has an unknown field ''sigmas'' \(expected point, mean, sigma, covariance, ', ...
       'sqrt_info, loss or loss_scale\)\.$']
    struct('point_priors', struct('point', 5)), 'sba:invalidArgument', ...
      'point_priors\(1\)\.mean must be given \(it is missing or empty\)\.$'
    struct('point_priors', setfield(pp, 'point', 0)), 'sba:invalidArgument', ...
      ['point_priors\(1\)\.point ', one, ' \(got 0\)\.$']
    struct('point_priors', setfield(pp, 'point', 2.5)), 'sba:invalidArgument', ...
      ['point_priors\(1\)\.point ', one, ' \(got 2.5\)\.$']
    struct('point_priors', setfield(pp, 'point', [1 2])), 'sba:invalidArgument', ...
      'point_priors\(1\)\.point must be a real numeric scalar \(got a 1x2 double\)\.$'
    struct('point_priors', setfield(pp, 'point', true)), 'sba:invalidArgument', ...
      'point_priors\(1\)\.point must be a dense real numeric array \(got a 1x1 logical\)\.$'
    struct('point_priors', [pp, setfield(pp, 'mean', [1 2])]), 'sba:wrongSize', ...
      'point_priors\(2\)\.mean must have pnp = 3 values \(got 2\)\.$'
    struct('point_priors', setfield(pp, 'mean', eye(3))), 'sba:wrongSize', ...
      'point_priors\(1\)\.mean must have pnp = 3 values \(got a 3 x 3 matrix\)\.$'
    struct('point_priors', setfield(pp, 'sigma', [1 1])), 'sba:wrongSize', ...
      'point_priors\(1\)\.sigma must have pnp = 3 values \(got 2\)\.$'
    struct('point_priors', setfield(rmfield(pp, 'sigma'), 'covariance', eye(2))), 'sba:wrongSize', ...
      'point_priors\(1\)\.covariance must be pnp x pnp = 3 x 3 \(got 2 x 2\)\.$'
    struct('point_priors', setfield(rmfield(pp, 'sigma'), 'sqrt_info', ones(3, 1))), 'sba:wrongSize', ...
      'point_priors\(1\)\.sqrt_info must be pnp x pnp = 3 x 3 \(got 3 x 1\)\.$'
    struct('point_priors', setfield(pp, 'loss', 3)), 'sba:invalidArgument', ...
      'point_priors\(1\)\.loss must be a string \(got a 1x1 double\)\.$'
    struct('point_priors', setfield(pp, 'loss_scale', [1 2])), 'sba:invalidArgument', ...
      'point_priors\(1\)\.loss_scale must be a real numeric scalar \(got a 1x2 double\)\.$'
    struct('camera_linear_priors', setfield(lp, 'params', [7 0])), 'sba:invalidArgument', ...
      ['camera_linear_priors\(1\)\.params\(2\) ', one, ' \(got 0\)\.$']
    struct('camera_linear_priors', setfield(lp, 'params', [6 7])), 'sba:wrongSize', ...
      'camera_linear_priors\(1\)\.mean must have numel\(params\) = 2 values \(got 1\)\.$'
    struct('camera_linear_priors', setfield(lp, 'params', [6 7; 1 2])), 'sba:invalidArgument', ...
      'camera_linear_priors\(1\)\.params must be a vector of parameter indices \(got a 2x2 double\)\.$'
    struct('camera_linear_priors', rmfield(lp, 'params')), 'sba:invalidArgument', ...
      'camera_linear_priors\(1\)\.params must be given'
    struct('camera_priors', setfield(cp, 'func', 3)), 'sba:invalidArgument', ...
      'camera_priors\(1\)\.func must be a function name or a function handle \(got a 1x1 double\)\.$'
    struct('camera_priors', setfield(cp, 'dim', 0.5)), 'sba:invalidArgument', ...
      'camera_priors\(1\)\.dim must be a whole number within \[-2147483648, 2147483647\] \(got 0.5\)\.$'
    struct('camera_priors', setfield(cp, 'sigma', [1 1])), 'sba:wrongSize', ...
      'camera_priors\(1\)\.sigma must have dim = 1 values \(got 2\)\.$'
    struct('camera_priors', setfield(cp, 'params', 7)), 'sba:invalidArgument', ...
      ['camera_priors has an unknown field ''params'' \(expected camera, dim, func, jac, sigma, ', ...
       'covariance, sqrt_info, loss or loss_scale\)\.$']
    struct('camera_priors', setfield(cp, 'func', 'sbatest_no_such_function')), 'sba:functionNotFound', ...
      'camera_priors\(1\)\.func: no function named ''sbatest_no_such_function'' was found\.$'
    struct('camera_priors', setfield(cp, 'func', @(j, a) [1 2])), 'sba:callbackSize', ...
      ['camera_priors\(1\)\.func returned a 1x2 double at camera 2; expected a real vector of ', ...
       'dim = 1 values\.$']
    struct('camera_priors', setfield(cp, 'func', @(j, a) error('boom %d', j))), 'sba:callbackFailed', ...
      'camera_priors\(1\)\.func failed at camera 2: boom 2$'
    struct('camera_priors', setfield(cp, 'jac', @(j, a) [0 1])), 'sba:callbackSize', ...
      ['camera_priors\(1\)\.jac returned a 1x2 double at camera 2; expected dim\*cnp = 7 values ', ...
       '\(1 x 7\)\.$']
    struct('point_priors', pp, 'fixed_param', 1), 'sba:invalidArgument', ...
      ['the options struct has an unknown field ''fixed_param'' \(expected fixed_params, camera_groups, ', ...
       'shared_params, param_groups, point_priors, camera_linear_priors or camera_priors\)\.$']
    % The library's check: its message names the prior, counting from 0 as C does.
    struct('point_priors', setfield(pp, 'mean', [1 NaN 3])), 'sba:invalidProblem', ...
      'point prior 0 \(point 4\): mean\[1\] is not finite$'
    struct('point_priors', [pp, setfield(pp, 'point', 41)]), 'sba:invalidProblem', ...
      'point prior 1 \(point 40\): there is no such point \(n = 40\)$'
    struct('point_priors', setfield(rmfield(pp, 'sigma'), 'covariance', [1 2 0; 2 1 0; 0 0 1])), ...
      'sba:invalidProblem', 'point prior 0 \(point 4\): weight.covariance is not positive definite$'
    struct('point_priors', setfield(pp, 'covariance', eye(3))), 'sba:invalidProblem', ...
      'point prior 0 \(point 4\): give at most one of weight.sigma, weight.covariance and weight.sqrt_info$'
    struct('point_priors', setfield(rmfield(pp, 'sigma'), 'sqrt_info', [1 0.5 0; 0 1 0.5; 0 0 1]')), ...
      'sba:invalidProblem', 'point prior 0 \(point 4\): weight.sqrt_info must be upper triangular \(entry \(1, 0\) is 0.5\)$'
    struct('point_priors', setfield(pp, 'loss', 'hubber')), 'sba:invalidProblem', ...
      'point prior 0 \(point 4\): unknown loss "hubber"'
    struct('point_priors', setfield(pp, 'sigma', [1 0 1])), 'sba:invalidProblem', ...
      'point prior 0 \(point 4\): weight.sigma\[1\] \(a standard deviation\) must be finite and positive \(got 0\)$'
    struct('camera_linear_priors', lp, 'fixed_params', [0 0 0 0 0 0 1]), 'sba:invalidProblem', ...
      ['camera linear prior 0 \(camera 1\): params\[0\] = 6 is held \(cam_fixed\): a prior on a held ', ...
       'parameter would change nothing$']
    struct('camera_linear_priors', setfield(lp, 'params', 8)), 'sba:invalidProblem', ...
      'camera linear prior 0 \(camera 1\): params\[0\] = 7 is not a camera parameter \(cnp = 7\)$'
    struct('camera_priors', setfield(cp, 'camera', 7)), 'sba:invalidProblem', ...
      'camera prior 0 \(camera 6\): there is no such camera \(m = 6\)$'
    struct('camera_priors', setfield(cp, 'dim', 0)), 'sba:invalidProblem', ...
      'camera prior 0 \(camera 1\): dim must be in 1..64 \(got 0\)$'
  };
  base = scene_args(s);
  for c = 1:size(cases, 1)
    sbatest_expect_error([base, {'motstr', cases{c, 1}}], cases{c, 2}, cases{c, 3});
  end
  % Priors on what the driver does not refine, or on a held camera.
  sbatest_expect_error([base, {'str', struct('camera_linear_priors', lp)}], 'sba:invalidProblem', ...
                       'camera linear prior 0 \(camera 1\): the driver has no cameras \(structure only\)$');
  sbatest_expect_error([base, {'mot', struct('point_priors', pp)}], 'sba:invalidProblem', ...
                       'point prior 0 \(point 4\): the driver has no points \(motion only\)$');
  base{4} = 2;                                % mcon 2: camera 2 is held
  sbatest_expect_error([base, {'motstr', struct('camera_priors', cp)}], 'sba:invalidProblem', ...
                       'camera prior 0 \(camera 1\): the camera is fixed \(below mcon = 2\)$');
  printf('%d bad priors refused\n', size(cases, 1) + 3);
end

% The projections' plain squared error at p.
function e = run_error(s, p)
  e = 0;
  q = 1;
  for i = 1:s.n
    for j = 1:s.m
      d = sbatest_focal_proj(j - 1, i - 1, p(7 * j - 6:7 * j), p(42 + 3 * i - 2:42 + 3 * i)) - s.x(q:q + 1);
      e = e + d * d';
      q = q + 2;
    end
  end
end

function varargout = run_scene(s, varargin)
  args = scene_args(s);
  [varargout{1:nargout}] = sba(args{:}, varargin{:});
end

% sba's arguments up to opts for the scene s: camera 1 held, finite-difference Jacobians,
% 200 iterations.
function args = scene_args(s)
  args = {s.n, 0, s.m, 1, s.vmask, s.p0, s.cnp, s.pnp, s.x, s.mnp, s.proj, '', ...
          200, 0, []};
end
