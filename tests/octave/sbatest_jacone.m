function A = sbatest_jacone(j, i, aj, bi, qr0, cal)
% A 'motstr' Jacobian that returns A only.
  A = sbaeuc_projac(j, i, aj, bi, qr0, cal);
end
% SPDX-License-Identifier: BSD-3-Clause
