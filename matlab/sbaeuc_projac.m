function [A, B] = sbaeuc_projac(j, i, aj, bi, qr0, cal)
% SBAEUC_PROJAC  Jacobians of SBAEUC_PROJ for reftype 'motstr'.
%
%   [A, B] = sbaeuc_projac(j, i, aj, bi, qr0, cal)
%
% A = dx/daj (2 x 6) and B = dx/dbi (2 x 3), returned as row-major vectors (1 x 12 and
% 1 x 6) as sba expects. Arguments as for SBAEUC_PROJ.
%
% Derivation. Let Y = R0 b with R0 = R(q0_j), qs = (w, u) the rotation correction (u = v and
% w = sqrt(1 - |v|^2) inside the unit ball) and Xc = R(qs) Y + t. For a unit quaternion,
%   R(qs) Y = Y + 2w (u x Y) + 2 u x (u x Y),  and  u x (u x Y) = u (u.Y) - Y (u.u),
% so
%   d(R(qs) Y)/du = -2w [Y]x + 2 ((u.Y) I + u Y' - 2 Y u'),   d(R(qs) Y)/dw = 2 (u x Y),
% where [Y]x is the matrix of Y x (.), since d(u x Y)/du = -[Y]x. With du/dv = I and
% dw/dv = -v'/w (outside the unit ball u = v/|v|: du/dv = (I - u u')/|v|, w = 0),
%   dXc/dv = d(R(qs) Y)/du * du/dv + 2 (u x Y) * dw/dv,   dXc/dt = I,   dXc/db = R(qs) R0.
% The pixel is K applied to (Xc(1)/Xc(3), Xc(2)/Xc(3)), so
%   H = dx/dXc = [fu s; 0 fu*ar] * [1/Z 0 -X/Z^2; 0 1/Z -Y/Z^2]     (Xc = (X, Y, Z))
% and A = [H * dXc/dv, H], B = H * R(qs) R0.
%
% See also SBAEUC_PROJ, SBAEUC_PROJAC_MOT, SBAEUC_PROJAC_STR, SBA.

  q = qr0(4*j+1:4*j+4);
  R0 = rotation(q(1), q(2), q(3), q(4));
  b = [bi(1); bi(2); bi(3)];
  v = [aj(1); aj(2); aj(3)];
  vv = v' * v;
  if vv < 1
    w = sqrt(1 - vv); u = v;
    dw = -v' / w; du = eye(3);
  else
    s = sqrt(vv); w = 0; u = v / s;
    dw = zeros(1, 3); du = (eye(3) - u * u') / s;
  end
  Rs = rotation(w, u(1), u(2), u(3));
  Y = R0 * b;
  Xc = Rs * Y + [aj(4); aj(5); aj(6)];

  fu = cal(1); ar = cal(4); sk = cal(5);
  iz = 1 / Xc(3);
  H = [fu, sk; 0, fu*ar] * [iz, 0, -Xc(1)*iz*iz; 0, iz, -Xc(2)*iz*iz];

  uxY = [u(2)*Y(3) - u(3)*Y(2); u(3)*Y(1) - u(1)*Y(3); u(1)*Y(2) - u(2)*Y(1)];
  Yx = [0, -Y(3), Y(2); Y(3), 0, -Y(1); -Y(2), Y(1), 0];
  dRY_du = -2*w*Yx + 2*((u'*Y)*eye(3) + u*Y' - 2*Y*u');
  Jv = dRY_du * du + 2 * uxY * dw;

  Am = [H * Jv, H];
  A = reshape(Am', 1, []);
  if nargout > 1
    Bm = H * Rs * R0;
    B = reshape(Bm', 1, []);
  end
end

function R = rotation(w, x, y, z)
  R = [w*w + x*x - y*y - z*z, 2*(x*y - w*z), 2*(x*z + w*y);
       2*(x*y + w*z), w*w - x*x + y*y - z*z, 2*(y*z - w*x);
       2*(x*z - w*y), 2*(y*z + w*x), w*w - x*x - y*y + z*z];
end
% SPDX-License-Identifier: BSD-3-Clause
