function test_demo_lib()
% (b) The demo script with NAME@LIBRARY callbacks reaches the C eucsbademo's final error,
% and so does its finite-difference variant with the C projection.
  ref = sbatest_reference('motstr');
  [cams, pts, calib] = sbatest_files();
  lib = sbatest_lib();
  [ret, popt, info, prob] = eucsbademo(cams, pts, calib, 'callbacks', 'lib', 'library', lib);
  sbatest_assert(ret > 0, 'sba returned %d', ret);
  sbatest_same5(info(2) / prob.nvis, ref, '(b) NAME@LIBRARY callbacks: final error');

  % A relative library name is found in the current directory.
  old = cd(fileparts(lib));
  restore = onCleanup(@() cd(old));
  [ret2, ~, info2] = eucsbademo(cams, pts, calib, 'callbacks', 'lib', 'library', ...
                                'libsbaeuc_proj.so', 'quiet', true);
  sbatest_assert(ret2 == ret && info2(2) == info(2), 'a relative library path gives another result');
  clear restore;

  [ret, ~, info] = eucsbademo(cams, pts, calib, 'callbacks', 'libfd', 'library', lib);
  sbatest_assert(ret > 0, 'sba returned %d', ret);
  sbatest_same5(info(2) / prob.nvis, sbatest_reference('motstr', 'numeric'), ...
                '(b) C projection, finite-difference Jacobian: final error');
end
% SPDX-License-Identifier: BSD-3-Clause
