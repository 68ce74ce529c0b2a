function [A, B] = sbatest_jacbad(j, i, aj, bi, qr0, cal)
% A Jacobian whose B has 5 values instead of mnp*pnp = 6.
  [A, B] = sbaeuc_projac(j, i, aj, bi, qr0, cal);
  B = B(1:5);
end
% SPDX-License-Identifier: BSD-3-Clause
