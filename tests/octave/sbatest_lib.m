function lib = sbatest_lib(name)
% SBATEST_LIB  Full path of a callbacks library of the build: libsbaeuc_proj.so beside the
% MEX file, or (name 'slow') the test library with the slow projection, or (name 'focal')
% the one with SBATEST_FOCAL_PROJ in C.
  if nargin > 0 && strcmp(name, 'slow')
    lib = fullfile(getenv('SBA_OCTAVE_TEST_DIR'), 'libsba_octave_slowproj.so');
  elseif nargin > 0 && strcmp(name, 'focal')
    lib = fullfile(getenv('SBA_OCTAVE_TEST_DIR'), 'libsba_octave_focal.so');
  else
    lib = fullfile(getenv('SBA_MEX_DIR'), 'libsbaeuc_proj.so');
  end
  sbatest_assert(exist(lib, 'file') == 2, 'the callbacks library %s is missing', lib);
end
% SPDX-License-Identifier: BSD-3-Clause
