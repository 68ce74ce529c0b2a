function [cams, pts, calib] = sbatest_files()
% SBATEST_FILES  The 7-camera demo problem of the shared data directory.
  d = fullfile(getenv('SBA_SHARED_DATA_DIR'), 'sba-demo');
  cams = fullfile(d, '7cams.txt');
  pts = fullfile(d, '7pts.txt');
  calib = fullfile(d, 'calib.txt');
end
% SPDX-License-Identifier: BSD-3-Clause
