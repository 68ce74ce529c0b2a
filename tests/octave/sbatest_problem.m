function prob = sbatest_problem()
% SBATEST_PROBLEM  The 7-camera demo problem as read by SBAEUC_READ (read once per session).
  persistent cached
  if isempty(cached)
    [cams, pts, calib] = sbatest_files();
    cached = sbaeuc_read(cams, pts, calib);
  end
  prob = cached;
end
% SPDX-License-Identifier: BSD-3-Clause
