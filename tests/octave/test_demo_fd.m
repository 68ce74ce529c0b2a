function test_demo_fd()
% (c) The demo script with the .m projection and finite differences (projac '') reaches the
% C eucsbademo's final error.
  ref = sbatest_reference('motstr', 'numeric');
  [cams, pts, calib] = sbatest_files();
  [ret, ~, info, prob] = eucsbademo(cams, pts, calib, 'callbacks', 'fd');
  sbatest_assert(ret > 0, 'sba returned %d', ret);
  sbatest_assert(info(9) == ret, 'Jacobian evaluations %g for %d iterations', info(9), ret);
  sbatest_same5(info(2) / prob.nvis, ref, '(c) finite differences: final error');
end
