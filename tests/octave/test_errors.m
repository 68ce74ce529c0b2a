function test_errors()
% Every bad argument is caught with try/catch with a clear message (and identifier), and
% the session keeps working.
  prob = sbatest_problem();
  lib = sbatest_lib();
  P = ['sbaeuc_proj@' lib];
  J = ['sbaeuc_projac@' lib];
  base = {prob.n, 0, prob.m, 0, prob.vmask, prob.p0, 6, 3, prob.x, 2, P, J, 20, 0, [], ...
          'motstr', prob.qr0, prob.cal};
  % slot numbers in base
  N = 1; NCON = 2; M = 3; MCON = 4; VMASK = 5; P0 = 6; CNP = 7; X = 9; MNP = 10; PROJ = 11;
  JAC = 12; ITMAX = 13; OPTS = 15; REF = 16; EXTRA = 17;
  x_nan = prob.x; x_nan(5) = NaN;
  p0_cplx = complex(prob.p0, 0);

  cases = {
    % slot, value, identifier, message (regular expression)
    N, 'abc', 'sba:invalidArgument', '^sba: n must be a positive integer scalar \(got a 1x3 char\)\.$'
    N, 0, 'sba:invalidArgument', 'n must be a positive integer scalar >= 1 \(got 0\)'
    N, 2.5, 'sba:invalidArgument', 'n must be a positive integer scalar >= 1 \(got 2\.5\)'
    N, [465 1], 'sba:invalidArgument', 'n must be a positive integer scalar \(got a 1x2 double\)'
    NCON, -1, 'sba:invalidArgument', 'ncon must be an integer scalar in \[0, 465\] \(got -1\)'
    M, {7}, 'sba:invalidArgument', 'm must be a positive integer scalar \(got a 1x1 cell\)'
    MCON, 8, 'sba:invalidArgument', 'mcon must be an integer scalar in \[0, 7\] \(got 8\)'
    VMASK, {1}, 'sba:invalidArgument', 'vmask must be a real n x m matrix \(got a 1x1 cell\)'
    VMASK, prob.vmask', 'sba:wrongSize', 'vmask must be n x m = 465 x 7 \(got 7 x 465\)'
    VMASK, false(465, 7), 'sba:invalidArgument', 'vmask has no nonzero entry'
    P0, prob.p0(1:end-1), 'sba:wrongSize', 'p0 must have m\*cnp \+ n\*pnp = 1437 values \(got 1436\)'
    P0, p0_cplx, 'sba:invalidArgument', 'p0 must be a real vector \(got a 1x1437 complex double\)'
    P0, reshape(prob.p0(1:1437), 3, 479), 'sba:invalidArgument', 'p0 must be a real vector \(got a 3x479 double\)'
    CNP, -6, 'sba:invalidArgument', 'cnp must be a non-negative integer scalar'
    X, 'abc', 'sba:invalidArgument', 'x must be a real vector \(got a 1x3 char\)'
    X, prob.x(1:end-2), 'sba:wrongSize', 'x must have nvis\*mnp \(nvis: the nonzeros of vmask\) = 3832 values \(got 3830\)'
    X, x_nan, 'sba:invalidArgument', 'x\(5\) is not finite'
    MNP, 0, 'sba:invalidArgument', 'mnp must be a positive integer scalar in \[1, 1048576\] \(got 0\)'
    PROJ, 5, 'sba:invalidArgument', 'proj must be a function name or ''NAME@LIBRARY'''
    PROJ, 'sbaeuc_proj@/nonexistent/libnothere.so', 'sba:libraryNotFound', ...
      'cannot load the library ''/nonexistent/libnothere.so'' of proj: .*No such file'
    PROJ, ['nosuchfunction@' lib], 'sba:functionNotFound', ...
      'the function ''nosuchfunction'' of proj is not in the library ''.*libsbaeuc_proj.so'''
    PROJ, ['@' lib], 'sba:invalidArgument', 'proj ''@.*'' must be NAME@LIBRARY with both parts given'
    JAC, 'sbaeuc_projac@libsurelymissing.so', 'sba:libraryNotFound', ...
      'cannot load the library ''libsurelymissing.so'' of projac'
    PROJ, 'no_such_function_xyz', 'sba:functionNotFound', 'proj: no function named ''no_such_function_xyz'' was found'
    JAC, 'no_such_jacobian_xyz', 'sba:functionNotFound', 'projac: no function named ''no_such_jacobian_xyz'' was found'
    ITMAX, -1, 'sba:invalidArgument', 'itmax must be a non-negative integer scalar >= 0 \(got -1\)'
    OPTS, [1e-3 NaN], 'sba:invalidArgument', 'opts\(2\) is not finite'
    REF, 'motion', 'sba:unknownReftype', 'unknown reftype ''motion'' \(expected ''motstr'', ''mot'' or ''str''\)'
    EXTRA, {1, 2}, 'sba:invalidArgument', 'extra argument 1 must be a real dense double array for NAME@LIBRARY callbacks \(got a 1x2 cell\)'
    PROJ, 'sbatest_proj3', 'sba:callbackSize', ...
      '^sba: proj ''sbatest_proj3'' returned a 1x3 double at camera 0, point 0; expected a real vector of mnp = 2 values\.$'
    PROJ, 'sbatest_projbadlater', 'sba:callbackSize', ...
      'proj ''sbatest_projbadlater'' returned a 1x1 double at camera 3, point [0-9]+; expected a real vector of mnp = 2 values'
    PROJ, 'sbatest_projfail', 'sba:callbackFailed', ...
      'proj ''sbatest_projfail'' failed at camera 5, point ([0-9]+): boom at camera 5, point \1$'
    JAC, 'sbatest_jacbad', 'sba:callbackSize', ...
      'projac ''sbatest_jacbad'' returned a 1x5 double as Bij at camera 0, point 0; expected mnp\*pnp = 6 values \(2 x 3\)'
    JAC, 'sbatest_jacone', 'sba:callbackFailed', ...
      'projac ''sbatest_jacone'' failed at camera 0, point 0: .*'
  };
  for k = 1:size(cases, 1)
    args = base;
    args{cases{k, 1}} = cases{k, 2};
    sbatest_expect_error(args, cases{k, 3}, cases{k, 4});
  end

  % Wrong covx length (covx given right after x).
  args = [base(1:X), {ones(1, 10)}, base(X+1:end)];
  sbatest_expect_error(args, 'sba:wrongSize', 'covx must have nvis\*mnp\*mnp = 7664 values \(got 10\)');
  % Everything fixed: the solver refuses the problem.
  args = base; args{MCON} = prob.m; args{NCON} = prob.n;
  sbatest_expect_error(args, 'sba:invalidProblem', 'the solver refused the problem: .*nothing to refine');
  % Too few inputs, too many outputs.
  sbatest_expect_error({1, 2, 3}, 'sba:notEnoughInputs', 'at least 12 input arguments are needed');
  try
    [a, b, c, d] = sba(base{:});
    error('sbatest:failed', 'four outputs were accepted');
  catch err
    sbatest_check_error(err, 'sba:tooManyOutputs', 'at most 3 outputs');
  end
  % A wrong number of outputs of the C function cannot be checked, but a missing Jacobian of
  % the right name in the wrong mode can: 'mot' with the motstr .m Jacobian asks for 1 output.
  args = base; args{PROJ} = 'sbaeuc_proj'; args{JAC} = 'sbaeuc_projac'; args{REF} = 'mot';
  args{ITMAX} = 1;
  [ret, ~, info] = sba(args{:});
  sbatest_assert(ret == 1 && isfinite(info(2)), 'mot with a two-output Jacobian failed');

  % A solver failure (not a bad argument): ret -1 with the reason in info and a warning.
  args = base; args{PROJ} = 'sbatest_projnan'; args{JAC} = 'sbaeuc_projac';
  lastwarn('');
  [ret, popt, info] = sba(args{:});
  [msg, id] = lastwarn();
  sbatest_assert(ret == -1 && info(7) == 7 && isequal(popt, prob.p0), ...
                 'NaN projections: ret %d, reason %g', ret, info(7));
  sbatest_assert(strcmp(id, 'sba:solverFailed') && ~isempty(strfind(msg, 'NaN')), ...
                 'NaN projections: warning "%s" (%s)', msg, id);
  printf('ok: solver failure returns -1 and warns: %s\n', msg);

  % The C callbacks called without their extra data answer NaN instead of crashing.
  lastwarn('');
  [ret, ~, info] = sba(base{1:REF});
  [msg, id] = lastwarn();
  sbatest_assert(ret == -1 && info(7) == 7 && strcmp(id, 'sba:solverFailed'), ...
                 'C callbacks without extra data: ret %d, reason %g, warning %s', ret, info(7), id);
  printf('ok: C callbacks without their extra data: ret -1, %s\n', msg);

  % After all that, a normal solve still works.
  [ret, ~, info] = sba(base{:});
  sbatest_assert(ret > 0 && info(2) / prob.nvis < 1, 'sba no longer works after the errors (ret %d)', ret);
end
% SPDX-License-Identifier: BSD-3-Clause
