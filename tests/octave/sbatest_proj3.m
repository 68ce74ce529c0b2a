function x = sbatest_proj3(j, i, aj, bi, qr0, cal)
% A projection that returns 3 values instead of mnp = 2 (for the error tests).
  x = [sbaeuc_proj(j, i, aj, bi, qr0, cal), 0];
end
% SPDX-License-Identifier: BSD-3-Clause
