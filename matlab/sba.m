function varargout = sba(varargin)
% SBA  Generic sparse bundle adjustment (MEX interface of the sba 1.6 simple drivers).
%
%   [ret, popt, info] = sba(n, ncon, m, mcon, vmask, p0, cnp, pnp, x, covx, mnp, proj,
%                           projac, itmax, verbose, opts, reftype, extra1, extra2, ...)
%
% Refines the parameters of m cameras and n 3D points so that the predicted projections of
% the points match the measured ones x in the least-squares sense, with sba's sparse
% Levenberg-Marquardt algorithm (M. Lourakis and A. Argyros, ACM TOMS 36(1), 2009).
%
% Required arguments
%   n       number of points
%   ncon    the points 1..ncon (zero-based 0..ncon-1) are held fixed
%   m       number of cameras (images)
%   mcon    the cameras 1..mcon are held fixed
%   vmask   n x m visibility mask, dense or sparse: vmask(i, j) nonzero iff point i is
%           seen in image j (any numeric or logical class)
%   p0      initial parameters, a row or column vector (a_1 .. a_m, b_1 .. b_n) of
%           m*cnp + n*pnp values: the camera parameters a_j, then the point parameters b_i
%   cnp     number of parameters of a camera
%   pnp     number of parameters of a point
%   x       the measured projections, nvis*mnp values (nvis = nnz(vmask)), point by point
%           and, for each point, camera after camera in increasing order:
%           x_11 .. x_1m, x_21 .. (only the visible ones)
%   mnp     number of coordinates of a projection (2 for image points)
%   proj    the projection function: the name of a MATLAB/Octave function or
%           'NAME@LIBRARY', the C function NAME of the shared library LIBRARY (see below)
%   itmax   maximum number of iterations; 0 checks the analytic Jacobian projac against
%           finite differences and reports suspicious entries instead of solving
%
% Optional arguments, recognised by their type and position
%   covx    right after x: the covariances of the measurements, nvis*mnp*mnp values, one
%           mnp x mnp matrix per projection in x's order. [] or absent: identity. (A scalar
%           right after x is mnp.)
%   projac  right after proj: the Jacobian function, a name or 'NAME@LIBRARY'; '' or absent:
%           finite-difference approximation from proj
%   verbose a scalar after itmax: how much to print (default 0). Nonzero prints, through the
%           host's print function, the solver's messages and the summary lines of the C
%           program eucsbademo ('SBA using ...', 'SBA returned ...', 'Elapsed time ...').
%   opts    a vector of at most 5 values after verbose, [tau eps1 eps2 eps3 eps4]: the
%           initial damping scale mu = tau * max(diag(J'J)) and the thresholds of the
%           stopping rules ||J'e||_inf <= eps1, ||dp||^2 <= eps2^2 ||p||^2, ||e||^2 <= eps3^2
%           and (if eps4 > 0) relative reduction of the RMS error below eps4.
%           Default [1e-3 1e-12 1e-12 1e-12 0]. [] takes the defaults; a shorter vector takes
%           the defaults for the missing values, with a warning.
%   reftype a string: 'motstr' (default) refines motion and structure, 'mot' motion only
%           (the points keep their values of p0), 'str' structure only (the cameras keep
%           their values of p0); case-insensitive
%   'strategy=NAME'  (beyond sba 1.6; just before or just after reftype) how the
%           Levenberg-Marquardt iteration damps and stops: 'strategy=sba' (1.6's algorithm,
%           the default unless the environment variable SBA_STRATEGY says otherwise),
%           'strategy=sba-clean-retry' (the same, but a rejected step is retried on the
%           undamped normal equations, as the sba paper writes it) or
%           'strategy=trust-region' (damping scaled by diag(J'J), Ceres-like stopping at a
%           relative cost change of eps4, 1e-6 when eps4 is 0: usually far fewer iterations)
%   options struct  (beyond sba 1.6; just before or just after reftype) a scalar struct with
%           any of these fields, for the cameras ('motstr' and 'mot'):
%             fixed_params   cnp flags held in every camera, or an m x cnp matrix, row j for
%                            camera j-1: nonzero holds the parameter at its p0 value
%             camera_groups  m group numbers, -1 for a camera in no group, else in [0, m-1]
%             shared_params  cnp flags: the parameters the cameras of a group share, solved
%                            as one unknown (say one focal length for one physical camera)
%             param_groups   an m x cnp matrix of group numbers, row j for camera j-1:
%                            cameras with equal numbers (not -1) in column c share parameter
%                            c; -1 is a parameter of its own; the columns' numbers are
%                            unrelated (a rig: the focal length by camera, the pose by
%                            frame). Not with camera_groups and shared_params.
%           Flags are numeric or logical; group numbers are numeric, never logical (false
%           would be group 0). The same struct takes priors, residuals beside the
%           projections that keep a point or camera parameters near known values, each field
%           a struct array, one element per prior, indices 1-based:
%             point_priors          point, mean (pnp values): r = b_point - mean
%             camera_linear_priors  camera, params (k parameter indices), mean (k values):
%                                   r = a_camera(params) - mean
%             camera_priors         camera, dim, func, jac: r = func(j, aj, extra1, ...),
%                                   dim values, j the prior's camera (1-based, unlike proj's
%                                   j) and aj its parameters; func is a function name or
%                                   handle; jac (same call) returns dr/daj, dim x cnp; jac
%                                   '' or absent: forward differences
%           and in each, optionally, at most one weight, sigma (k standard deviations),
%           covariance (k x k) or sqrt_info (upper-triangular L, L'*L = inv(covariance)),
%           and loss ('huber', 'cauchy', 'soft-l1', 'tukey'; '' none) with loss_scale (the
%           prior's own). info(1) and info(2) then include the priors' cost. The library
%           checks the values (sba:invalidProblem), its message counting from 0: 'point
%           prior 0 (point 4)' is point_priors(1), on point 5.
%           A struct with none of these fields is problem data.
%   extra1, extra2, ...  everything after those: problem data passed unchanged to every call
%           of proj and projac (and of the priors' func and jac)
%
% Outputs
%   ret     the number of iterations, or -1 if the solver failed (with a warning that says
%           why, e.g. a singular system)
%   popt    the refined parameters, with the size and orientation of p0 (for 'mot' and 'str'
%           the fixed half is copied from p0)
%   info    1 x 10: [||e_0||^2, ||e||^2, ||J'e||_inf, ||dp||^2, mu/max(diag(J'J)),
%           iterations, stop reason, function evaluations, Jacobian evaluations, linear
%           systems solved]. The stop reason is 1: small gradient, 2: small dp, 3: itmax,
%           4: small relative error reduction, 5: small ||e||, 6: the damping could not grow,
%           7: proj or projac gave NaN/Inf, 8: singular system, 9: stopped on request
%           (the list lives in sba_ext.h, SBA_STOP_*; sba_stop_reason_text words each).
%           The mean squared reprojection error is info(2) / nvis (without priors).
%
% Callbacks
%   j and i are the zero-based camera and point indices; aj (cnp values) and bi (pnp values)
%   are passed as vectors with the orientation of p0, in every mode (for 'mot' bi holds the
%   fixed point, for 'str' aj the fixed camera):
%       xij = proj(j, i, aj, bi, extra1, extra2, ...)         mnp values
%       [Aij, Bij] = projac(j, i, aj, bi, extra1, ...)          'motstr'
%       Aij = projac(j, i, aj, bi, extra1, ...)                 'mot'
%       Bij = projac(j, i, aj, bi, extra1, ...)                 'str'
%   Aij = dxij/daj (mnp x cnp) and Bij = dxij/dbi (mnp x pnp) are returned as row-major
%   vectors (an mnp x cnp, resp. mnp x pnp, matrix is accepted too). Before solving, sba
%   calls proj and projac once on camera 0 and point 0 and stops with an error if what they
%   return has the wrong size; a callback that fails or returns a wrong size later stops the
%   solve with an error as well.
%
%   'NAME@LIBRARY' loads NAME from the shared library LIBRARY (a path; a bare file name is
%   looked for in the current directory first). Such callbacks run without the interpreter
%   and are much faster. Their C signatures, where adata[k] points to the doubles of the
%   k-th extra argument (extra arguments must then be real double arrays):
%     void proj(int j, int i, double *aj, double *bi, double *xij, double **adata);
%     'motstr': void projac(int j, int i, double *aj, double *bi, double *Aij, double *Bij,
%                           double **adata);
%     'mot':    void projac(int j, int i, double *aj, double *bi, double *Aij, double **adata);
%     'str':    void projac(int j, int i, double *aj, double *bi, double *Bij, double **adata);
%
% Errors and interruption
%   Every bad argument stops with an error naming it, e.g. 'sba: x must have nvis*mnp = 3832
%   values (got 3830).' Identifiers: sba:invalidArgument, sba:wrongSize, sba:notEnoughInputs,
%   sba:unknownReftype, sba:unknownStrategy, sba:libraryNotFound, sba:functionNotFound,
%   sba:callbackFailed, sba:callbackSize, sba:invalidProblem. Ctrl-C stops a running solve
%   cleanly between two callback calls (Octave; MATLAB through utIsInterruptPending), returns
%   no result and leaves the session working.
%
% Example: the Euclidean bundle adjustment of the C demo program,
%   eucsbademo                   % .m callbacks SBAEUC_PROJ and SBAEUC_PROJAC
%   eucsbademo(cams, pts, calib, 'callbacks', 'lib')   % the same in C
%
% See also EUCSBADEMO, SBAEUC_PROJ, SBAEUC_PROJAC, SBAEUC_PROJAC_MOT, SBAEUC_PROJAC_STR,
% SBAEUC_READ.

  % This file holds the help text; the work is done by the MEX file sba.mex (Octave) or
  % sba.mexa64 (MATLAB), which takes precedence over it once built.
  error('sba:notBuilt', ['sba: the MEX file of sba is not built or not on the path ', ...
        '(build the CMake target sba_mex, or run "make mex")']);
end
% SPDX-License-Identifier: BSD-3-Clause
