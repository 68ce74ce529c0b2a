function sba_octave_test(name)
% SBA_OCTAVE_TEST  Runs the test function NAME of the Octave tests of the sba MEX interface
% and exits Octave: status 0 when it passes or is skipped ("skipped: ..." printed), 1 when
% it fails (the failure printed). Used by ctest (tests/octave/CMakeLists.txt).
  status = 1;
  try
    if ~is_ready()
      printf('skipped: the shared data directory %s is absent\n', data_dir());
      status = 0;
    else
      t0 = tic;
      feval(name);
      printf('%s: passed (%.1f s)\n', name, toc(t0));
      status = 0;
    end
  catch err
    printf('%s: FAILED: %s\n', name, err.message);
    for k = 1:numel(err.stack)
      printf('  at %s line %d\n', err.stack(k).name, err.stack(k).line);
    end
  end
  fflush(stdout);
  exit(status);
end

function ok = is_ready()
  ok = exist(fullfile(data_dir(), 'sba-demo', '7cams.txt'), 'file') == 2;
end

function d = data_dir()
  d = getenv('SBA_SHARED_DATA_DIR');
end
% SPDX-License-Identifier: BSD-3-Clause
