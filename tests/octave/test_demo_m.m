function test_demo_m()
% (a) The demo script with the .m callbacks reaches the C eucsbademo's final error.
% Called without files, it takes them from SBA_DEMO_DATA, and says so when they are not there.
  ref = sbatest_reference('motstr');
  [cams, pts, calib] = sbatest_files();
  old = getenv('SBA_DEMO_DATA');
  setenv('SBA_DEMO_DATA', tempdir());
  try
    eucsbademo();
    error('sbatest:failed', 'eucsbademo without its files did not fail');
  catch err
    sbatest_assert(strcmp(err.identifier, 'eucsbademo:data') && ...
                   ~isempty(strfind(err.message, 'SBA_DEMO_DATA')), ...
                   'no demo files: %s (%s)', err.message, err.identifier);
    printf('ok: %s\n', err.message);
  end
  setenv('SBA_DEMO_DATA', fileparts(cams));
  [ret, popt, info, prob] = eucsbademo();
  setenv('SBA_DEMO_DATA', old);
  sbatest_assert(ret > 0, 'sba returned %d', ret);
  sbatest_assert(isequal(size(popt), size(prob.p0)), 'popt is %s, p0 %s', mat2str(size(popt)), ...
                 mat2str(size(prob.p0)));
  sbatest_assert(info(7) >= 1 && info(7) <= 6, 'stop reason %g', info(7));
  sbatest_same5(info(1) / prob.nvis, 19.0947, '(a) .m callbacks: initial error');
  sbatest_same5(info(2) / prob.nvis, ref, '(a) .m callbacks: final error');
end
% SPDX-License-Identifier: BSD-3-Clause
