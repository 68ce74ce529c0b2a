function x = sbatest_projnan(j, i, aj, bi, qr0, cal)
% A projection that returns NaN for camera 2: the solver fails (ret -1, stop reason 7).
  x = sbaeuc_proj(j, i, aj, bi, qr0, cal);
  if j == 2
    x = [NaN NaN];
  end
end
% SPDX-License-Identifier: BSD-3-Clause
