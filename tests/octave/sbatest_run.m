function [ret, popt, info] = sbatest_run(prob, varargin)
% SBATEST_RUN  sba on prob with the C callbacks of libsbaeuc_proj.so and defaults that the
% options override: 'reftype', 'itmax', 'opts', 'vmask', 'p0', 'covx', 'callbacks' ('lib',
% 'm' or 'libfd'), 'mcon', 'ncon', 'verbose'.
  o = struct('reftype', 'motstr', 'itmax', 150, 'opts', [1e-3 1e-12 1e-12 1e-12 0], ...
             'vmask', prob.vmask, 'p0', prob.p0, 'covx', prob.covx, 'callbacks', 'lib', ...
             'mcon', 0, 'ncon', 0, 'verbose', 0);
  for k = 1:2:numel(varargin)
    o.(varargin{k}) = varargin{k + 1};
  end
  jacs = struct('motstr', 'sbaeuc_projac', 'mot', 'sbaeuc_projac_mot', 'str', 'sbaeuc_projac_str');
  jac = jacs.(lower(o.reftype));
  proj = 'sbaeuc_proj';
  switch o.callbacks
    case 'lib'
      proj = [proj '@' sbatest_lib()];
      jac = [jac '@' sbatest_lib()];
    case 'libfd'
      proj = [proj '@' sbatest_lib()];
      jac = '';
  end
  [ret, popt, info] = sba(prob.n, o.ncon, prob.m, o.mcon, o.vmask, o.p0, prob.cnp, prob.pnp, ...
                          prob.x, o.covx, prob.mnp, proj, jac, o.itmax, o.verbose, o.opts, ...
                          o.reftype, prob.qr0, prob.cal);
end
% SPDX-License-Identifier: BSD-3-Clause
