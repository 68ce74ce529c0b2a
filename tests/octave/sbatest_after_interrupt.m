function sbatest_after_interrupt(kind)
% SBATEST_AFTER_INTERRUPT  Run after an interrupted SBATEST_LONG_SOLVE: checks that its
% result was never assigned and that sba still solves, and prints a marker line.
  global sbatest_result
  if ~ischar(sbatest_result) || ~strcmp(sbatest_result, 'untouched')
    printf('AFTER INTERRUPT (%s): FAILED: the interrupted solve assigned its result\n', kind);
    fflush(stdout);
    return;
  end
  prob = sbatest_problem();
  [ret, ~, info] = sbatest_run(prob);
  printf('AFTER INTERRUPT (%s): OK, a new solve returned %d with error %g\n', kind, ret, ...
         info(2) / prob.nvis);
  fflush(stdout);
end
% SPDX-License-Identifier: BSD-3-Clause
