function test_demo_fd()
% (c) The demo script with the .m projection and finite differences (projac '') reaches the
% C eucsbademo's final error.
  ref = sbatest_reference('motstr', 'numeric');
  [cams, pts, calib] = sbatest_files();
  [ret, ~, info, prob] = eucsbademo(cams, pts, calib, 'callbacks', 'fd');
  sbatest_assert(ret > 0, 'sba returned %d', ret);
  % The simple drivers count projac calls, as sba 1.6 does: one per visible projection per
  % Jacobian, finite differences included.
  sbatest_assert(info(9) == ret * prob.nvis, 'Jacobian evaluations %g for %d iterations of %d projections', ...
                 info(9), ret, prob.nvis);
  sbatest_same5(info(2) / prob.nvis, ref, '(c) finite differences: final error');
end
% SPDX-License-Identifier: BSD-3-Clause
