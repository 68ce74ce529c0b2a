function x = sbatest_projbadlater(j, i, aj, bi, qr0, cal)
% A projection that returns a wrong size for camera 3 only (found during the solve).
  x = sbaeuc_proj(j, i, aj, bi, qr0, cal);
  if j == 3
    x = x(1);
  end
end
% SPDX-License-Identifier: BSD-3-Clause
