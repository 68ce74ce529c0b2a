function [ret, popt, info, prob] = eucsbademo(camsfile, ptsfile, calibfile, varargin)
% EUCSBADEMO  Euclidean bundle adjustment of eucsbademo's problems with SBA.
%
%   eucsbademo
%   eucsbademo(camsfile, ptsfile, calibfile)
%   eucsbademo(..., 'callbacks', C, 'reftype', R, 'itmax', N, 'verbose', V, 'quiet', Q,
%              'library', LIB)
%   [ret, popt, info, prob] = eucsbademo(...)
%
% Refines the cameras and points of the text files of the C program eucsbademo (fixed
% intrinsics; see SBAEUC_READ for the formats) with the quaternion camera model of
% SBAEUC_PROJ and prints the same summary as eucsbademo:
%
%   SBA using 465 3D pts, 7 frames and 1916 image projections, 1437 variables
%
%   Method BA_MOTSTRUCT, simple driver, analytic Jacobian, without covariances, ...
%
%   SBA returned 18 in 18 iter, reason 2, error 0.675396 [initial 19.0947], ...
%   Elapsed time: ...
%
% Without file names it runs the 7-camera problem of sba's demo files (7cams.txt, 7pts.txt,
% calib.txt) in the directory named by the environment variable SBA_DEMO_DATA, else in the
% current directory.
%
% Options (name, value pairs):
%   'callbacks'  'm'   (default) the .m functions SBAEUC_PROJ and SBAEUC_PROJAC[_MOT|_STR]
%                'lib' the same functions in C, as 'NAME@LIBRARY' (libsbaeuc_proj.so)
%                'fd'  the .m projection with finite-difference Jacobians (projac '')
%                'libfd' the C projection with finite-difference Jacobians
%   'reftype'    'motstr' (default), 'mot' or 'str'
%   'itmax'      maximum iterations (default 150 for 'motstr', 100 otherwise, as eucsbademo)
%   'verbose'    passed to SBA (default 0)
%   'quiet'      true: print nothing (default false)
%   'library'    the shared library of the C callbacks (default: libsbaeuc_proj.so beside
%                the sba MEX file)
%
% ret, popt and info are those of SBA; prob is the problem as read (see SBAEUC_READ).
%
% See also SBA, SBAEUC_READ, SBAEUC_PROJ, SBAEUC_PROJAC.

  if nargin == 0
    dir = default_data_dir();
    camsfile = fullfile(dir, '7cams.txt');
    ptsfile = fullfile(dir, '7pts.txt');
    calibfile = fullfile(dir, 'calib.txt');
  elseif nargin < 3
    error('eucsbademo:args', 'give the camera, point and calibration files, or nothing');
  end
  opt = struct('callbacks', 'm', 'reftype', 'motstr', 'itmax', [], 'verbose', 0, ...
               'quiet', false, 'library', '');
  if mod(numel(varargin), 2) ~= 0
    error('eucsbademo:args', 'options come in name, value pairs');
  end
  for k = 1:2:numel(varargin)
    name = lower(varargin{k});
    if ~isfield(opt, name)
      error('eucsbademo:args', 'unknown option ''%s''', varargin{k});
    end
    opt.(name) = varargin{k + 1};
  end
  reftype = lower(opt.reftype);
  if isempty(opt.itmax)
    opt.itmax = 100;
    if strcmp(reftype, 'motstr')
      opt.itmax = 150;
    end
  end

  prob = sbaeuc_read(camsfile, ptsfile, calibfile);

  switch reftype
    case 'motstr'
      method = 'BA_MOTSTRUCT'; jac = 'sbaeuc_projac'; nvars = prob.m*prob.cnp + prob.n*prob.pnp;
    case 'mot'
      method = 'BA_MOT'; jac = 'sbaeuc_projac_mot'; nvars = prob.m*prob.cnp;
    case 'str'
      method = 'BA_STRUCT'; jac = 'sbaeuc_projac_str'; nvars = prob.n*prob.pnp;
    otherwise
      error('eucsbademo:args', 'unknown reftype ''%s''', opt.reftype);
  end
  proj = 'sbaeuc_proj';
  switch lower(opt.callbacks)
    case 'm'
    case 'fd'
      jac = '';
    case {'lib', 'libfd'}
      lib = opt.library;
      if isempty(lib)
        lib = fullfile(fileparts(which('sba')), 'libsbaeuc_proj.so');
      end
      proj = [proj '@' lib];
      if strcmpi(opt.callbacks, 'lib')
        jac = [jac '@' lib];
      else
        jac = '';
      end
    otherwise
      error('eucsbademo:args', 'unknown callbacks ''%s'' (m, lib, fd or libfd)', opt.callbacks);
  end

  if ~opt.quiet
    fprintf(2, 'Starting BA with fixed intrinsic parameters\n');
  end
  opts = [1e-3, 1e-12, 1e-12, 1e-12, 0];
  t0 = tic;
  [ret, popt, info] = sba(prob.n, 0, prob.m, 0, prob.vmask, prob.p0, prob.cnp, prob.pnp, ...
                          prob.x, prob.covx, prob.mnp, proj, jac, opt.itmax, opt.verbose, ...
                          opts, reftype, prob.qr0, prob.cal);
  seconds = toc(t0);

  if opt.quiet
    return;
  end
  if ret < 0
    fprintf(2, 'eucsbademo: sba failed (ret %d): no result\n', ret);
    return;
  end
  covtext = 'without';
  if ~isempty(prob.covx)
    covtext = 'with';
  end
  jactext = 'analytic';
  if isempty(jac)
    jactext = 'approximate';
  end
  fprintf('SBA using %d 3D pts, %d frames and %d image projections, %d variables\n', ...
          prob.n, prob.m, prob.nvis, nvars);
  fprintf('\nMethod %s, simple driver, %s Jacobian, %s covariances, without distortion, fixed intrinsics\n', ...
          method, jactext, covtext);
  fprintf(['\nSBA returned %d in %g iter, reason %g, error %g [initial %g], %d/%d func/fjac evals, ' ...
           '%d lin. systems\n'], ret, info(6), info(7), info(2) / prob.nvis, info(1) / prob.nvis, ...
          info(8), info(9), info(10));
  fprintf('Elapsed time: %.2f seconds, %.2f msecs\n', seconds, seconds * 1000);
end

function dir = default_data_dir()
  dir = getenv('SBA_DEMO_DATA');
  if isempty(dir)
    dir = pwd;
  end
  if ~exist(fullfile(dir, '7cams.txt'), 'file')
    error('eucsbademo:data', ['eucsbademo: no 7cams.txt in %s: give the camera, point and ' ...
          'calibration files, or set SBA_DEMO_DATA to the directory of sba''s demo files'], dir);
  end
end
% SPDX-License-Identifier: BSD-3-Clause
