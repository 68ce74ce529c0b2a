function A = sbaeuc_projac_mot(j, i, aj, bi, qr0, cal)
% SBAEUC_PROJAC_MOT  Jacobian of SBAEUC_PROJ for reftype 'mot' (motion only).
%
%   A = sbaeuc_projac_mot(j, i, aj, bi, qr0, cal)
%
% A = dx/daj, 2 x 6, as a row-major 1 x 12 vector; bi holds the fixed point. Arguments as
% for SBAEUC_PROJ; the derivation is in SBAEUC_PROJAC.
%
% See also SBAEUC_PROJ, SBAEUC_PROJAC, SBAEUC_PROJAC_STR, SBA.

  A = sbaeuc_projac(j, i, aj, bi, qr0, cal);
end
% SPDX-License-Identifier: BSD-3-Clause
