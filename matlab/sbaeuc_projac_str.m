function B = sbaeuc_projac_str(j, i, aj, bi, qr0, cal)
% SBAEUC_PROJAC_STR  Jacobian of SBAEUC_PROJ for reftype 'str' (structure only).
%
%   B = sbaeuc_projac_str(j, i, aj, bi, qr0, cal)
%
% B = dx/dbi = H * R(qs) * R(q0_j), 2 x 3, as a row-major 1 x 6 vector; aj holds the fixed
% camera. Arguments as for SBAEUC_PROJ; the derivation is in SBAEUC_PROJAC.
%
% See also SBAEUC_PROJ, SBAEUC_PROJAC, SBAEUC_PROJAC_MOT, SBA.

  [~, B] = sbaeuc_projac(j, i, aj, bi, qr0, cal);
end
% SPDX-License-Identifier: BSD-3-Clause
