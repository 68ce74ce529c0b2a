function sbatest_same5(got, want, what)
% SBATEST_SAME5  Fails unless got equals want to 5 significant digits; prints both.
  printf('%s: %.7g (reference %.7g)\n', what, got, want);
  sbatest_assert(isfinite(got) && abs(got - want) <= 5e-6 * abs(want), ...
                 '%s: %.9g differs from the reference %.9g in the first 5 significant digits', ...
                 what, got, want);
end
% SPDX-License-Identifier: BSD-3-Clause
