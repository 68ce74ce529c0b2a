function test_reftypes()
% 'mot' and 'str' refinements: the C callbacks reach the C eucsbademo's final errors, the fixed
% half of popt is p0's, and the .m callbacks (with their own mot/str Jacobians) give the same
% iterates as the C ones.
  prob = sbatest_problem();
  na = prob.m * prob.cnp;
  for r = {'mot', 'str'}
    reftype = r{1};
    ref = sbatest_reference(reftype);
    [ret, popt, info] = sbatest_run(prob, 'reftype', reftype, 'itmax', 100);
    sbatest_assert(ret > 0, '%s: sba returned %d', reftype, ret);
    sbatest_same5(info(2) / prob.nvis, ref, sprintf('reftype ''%s'', C callbacks: final error', reftype));
    if strcmp(reftype, 'mot')
      sbatest_assert(isequal(popt(na+1:end), prob.p0(na+1:end)), 'mot changed the points');
      sbatest_assert(~isequal(popt(1:na), prob.p0(1:na)), 'mot left the cameras alone');
    else
      sbatest_assert(isequal(popt(1:na), prob.p0(1:na)), 'str changed the cameras');
      sbatest_assert(~isequal(popt(na+1:end), prob.p0(na+1:end)), 'str left the points alone');
    end

    % Two iterations with the .m callbacks against the C callbacks.
    [retc, poptc, infoc] = sbatest_run(prob, 'reftype', reftype, 'itmax', 2);
    [retm, poptm, infom] = sbatest_run(prob, 'reftype', reftype, 'itmax', 2, 'callbacks', 'm');
    sbatest_assert(retc == 2 && retm == 2, '%s: %d and %d iterations instead of 2', reftype, retc, retm);
    d = max(abs(poptm - poptc)) / max(abs(poptc));
    printf('reftype ''%s'': .m and C callbacks after 2 iterations: error %.9g vs %.9g, max rel. dp %.2g\n', ...
           reftype, infom(2), infoc(2), d);
    sbatest_assert(abs(infom(2) - infoc(2)) <= 1e-9 * infoc(2) && d < 1e-9, ...
                   '%s: the .m callbacks (%.12g) and the C callbacks (%.12g) disagree', ...
                   reftype, infom(2), infoc(2));
  end

  % The .m Jacobians against central differences of the .m projection.
  rand('seed', 3);
  for trial = 1:5
    j = mod(trial * 3, prob.m); i = mod(trial * 97, prob.n);
    aj = prob.p0(j*6+1:j*6+6) + [0.05 * (rand(1, 3) - 0.5), 0, 0, 0];
    bi = prob.p0(na+i*3+1:na+i*3+3);
    [A, B] = sbaeuc_projac(j, i, aj, bi, prob.qr0, prob.cal);
    sbatest_assert(isequal(sbaeuc_projac_mot(j, i, aj, bi, prob.qr0, prob.cal), A), 'projac_mot differs');
    sbatest_assert(isequal(sbaeuc_projac_str(j, i, aj, bi, prob.qr0, prob.cal), B), 'projac_str differs');
    An = zeros(2, 6); Bn = zeros(2, 3);
    for k = 1:6
      h = 1e-6 * max(1, abs(aj(k))); e = zeros(1, 6); e(k) = h;
      An(:, k) = (sbaeuc_proj(j, i, aj + e, bi, prob.qr0, prob.cal) - ...
                  sbaeuc_proj(j, i, aj - e, bi, prob.qr0, prob.cal))' / (2 * h);
    end
    for k = 1:3
      h = 1e-7 * max(1e-3, abs(bi(k))); e = zeros(1, 3); e(k) = h;
      Bn(:, k) = (sbaeuc_proj(j, i, aj, bi + e, prob.qr0, prob.cal) - ...
                  sbaeuc_proj(j, i, aj, bi - e, prob.qr0, prob.cal))' / (2 * h);
    end
    ea = max(max(abs(reshape(A, 6, 2)' - An))) / max(abs(An(:)));
    eb = max(max(abs(reshape(B, 3, 2)' - Bn))) / max(abs(Bn(:)));
    sbatest_assert(ea < 1e-5 && eb < 1e-5, 'Jacobians vs central differences: rel. errors %g, %g', ea, eb);
  end
end
% SPDX-License-Identifier: BSD-3-Clause
