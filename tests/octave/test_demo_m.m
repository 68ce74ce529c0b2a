function test_demo_m()
% (a) The demo script with the .m callbacks reaches the C eucsbademo's final error.
  ref = sbatest_reference('motstr');
  [cams, pts, calib] = sbatest_files();
  [ret, popt, info, prob] = eucsbademo(cams, pts, calib, 'callbacks', 'm');
  sbatest_assert(ret > 0, 'sba returned %d', ret);
  sbatest_assert(isequal(size(popt), size(prob.p0)), 'popt is %s, p0 %s', mat2str(size(popt)), ...
                 mat2str(size(prob.p0)));
  sbatest_assert(info(7) >= 1 && info(7) <= 6, 'stop reason %g', info(7));
  sbatest_same5(info(1) / prob.nvis, 19.0947, '(a) .m callbacks: initial error');
  sbatest_same5(info(2) / prob.nvis, ref, '(a) .m callbacks: final error');
end
% SPDX-License-Identifier: BSD-3-Clause
