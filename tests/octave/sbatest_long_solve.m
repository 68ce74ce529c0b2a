function sbatest_long_solve(kind)
% SBATEST_LONG_SOLVE  Starts a solve that runs for a minute or more, for the Ctrl-C test:
% kind 'lib' (a slow C projection with finite differences: the library is working when the
% interrupt comes) or 'm' (the .m projection with finite differences: the interpreter is).
% Prints a marker line before and, should it ever finish, after the solve.
  prob = sbatest_problem();
  switch kind
    case 'lib'
      proj = ['sbaeuc_slowproj@' sbatest_lib('slow')];
    case 'm'
      proj = 'sbaeuc_proj';
  end
  global sbatest_result
  sbatest_result = 'untouched';
  printf('LONG SOLVE STARTED (%s)\n', kind);
  fflush(stdout);
  [ret, popt, info] = sba(prob.n, 0, prob.m, 0, prob.vmask, prob.p0, 6, 3, prob.x, 2, proj, '', ...
                          1000, 0, [1e-3 0 0 0 0], 'motstr', prob.qr0, prob.cal);
  sbatest_result = ret;
  printf('LONG SOLVE FINISHED (%s): ret %d\n', kind, ret);
  fflush(stdout);
end
% SPDX-License-Identifier: BSD-3-Clause
