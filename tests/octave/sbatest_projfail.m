function x = sbatest_projfail(j, i, aj, bi, qr0, cal)
% A projection that raises an error for camera 5 and point 40 (after the trial call).
  if j == 5 && i >= 40
    error('sbatest:boom', 'boom at camera %d, point %d', j, i);
  end
  x = sbaeuc_proj(j, i, aj, bi, qr0, cal);
end
% SPDX-License-Identifier: BSD-3-Clause
