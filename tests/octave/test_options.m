function test_options()
% covx, dense and sparse vmask, short and empty opts, row and column p0, verbose output,
% reftype case, mcon/ncon, itmax 0.
  prob = sbatest_problem();
  [ret0, popt0, info0] = sbatest_run(prob);
  sbatest_assert(ret0 > 0, 'sba returned %d', ret0);

  % Dense masks of several classes and the sparse one give identical results.
  for mask = {full(prob.vmask), double(full(prob.vmask)), uint8(full(prob.vmask)), ...
              sparse(double(prob.vmask)), single(full(prob.vmask))}
    [ret, popt, info] = sbatest_run(prob, 'vmask', mask{1});
    sbatest_assert(ret == ret0 && isequal(popt, popt0) && isequal(info, info0), ...
                   'a %s%s vmask gives another result than the sparse logical one', ...
                   ifelse(issparse(mask{1}), 'sparse ', ''), class(mask{1}));
  end
  % Explicit zeros stored in a sparse mask are not visible.
  [I, J] = find(prob.vmask);
  vz = sparse([I; 1], [J; 7], [ones(numel(I), 1); 0], prob.n, prob.m);
  if ~prob.vmask(1, 7)
    [ret, popt] = sbatest_run(prob, 'vmask', vz);
    sbatest_assert(ret == ret0 && isequal(popt, popt0), 'a stored zero of a sparse vmask counted');
  end
  printf('dense and sparse vmask: identical results\n');

  % Covariances: identities change nothing; 4 I divides the error by 4, same minimizer.
  eyes = repmat([1 0 0 1], 1, prob.nvis);
  [ret, popt, info] = sbatest_run(prob, 'covx', eyes);
  sbatest_assert(ret > 0 && abs(info(2) - info0(2)) <= 1e-9 * info0(2) && ...
                 max(abs(popt - popt0)) <= 1e-9 * max(abs(popt0)), ...
                 'identity covariances: error %.12g instead of %.12g', info(2), info0(2));
  [ret, popt, info] = sbatest_run(prob, 'covx', 4 * eyes);
  dp = max(abs(popt - popt0)) / max(abs(popt0));
  printf('covx = 4 I: error %.9g = %.9g / 4, max rel. parameter difference %.2g\n', info(2), info0(2), dp);
  sbatest_assert(ret > 0 && abs(4 * info(2) - info0(2)) <= 1e-6 * info0(2) && dp < 1e-6, ...
                 'covx = 4 I: error %.12g, expected %.12g / 4', info(2), info0(2));
  [ret, ~, info] = sbatest_run(prob, 'covx', []);
  sbatest_assert(ret == ret0 && isequal(info, info0), 'covx [] is not "no covariances"');

  % opts: [] and a short vector take the defaults; the short one warns.
  lastwarn('');
  [ret, popt, info] = sbatest_run(prob, 'opts', []);
  [msg, id] = lastwarn();
  sbatest_assert(ret == ret0 && isequal(popt, popt0) && isequal(info, info0), '[] opts: not the defaults');
  sbatest_assert(isempty(msg), '[] opts warned: %s', msg);
  lastwarn('');
  [ret, popt, info] = sbatest_run(prob, 'opts', [1e-3 1e-12]);
  [msg, id] = lastwarn();
  sbatest_assert(ret == ret0 && isequal(popt, popt0) && isequal(info, info0), 'short opts: not the defaults');
  sbatest_assert(strcmp(id, 'sba:shortOpts') && ~isempty(strfind(msg, 'opts has 2 of the 5 values')), ...
                 'short opts: warning "%s" (%s)', msg, id);
  printf('short opts warned: %s\n', msg);
  [ret, ~, info] = sbatest_run(prob, 'opts', [1e-3 1e-12 1e-12 1e-12 0]');
  sbatest_assert(ret == ret0 && isequal(info, info0), 'column opts differ');
  % opts omitted altogether (and verbose too): the defaults.
  lib = sbatest_lib();
  [ret, popt] = sba(prob.n, 0, prob.m, 0, prob.vmask, prob.p0, 6, 3, prob.x, 2, ...
                    ['sbaeuc_proj@' lib], ['sbaeuc_projac@' lib], 150, 'motstr', prob.qr0, prob.cal);
  sbatest_assert(ret == ret0 && isequal(popt, popt0), 'omitted covx/verbose/opts: not the defaults');
  [ret, popt] = sba(prob.n, 0, prob.m, 0, prob.vmask, prob.p0, 6, 3, prob.x, 2, ...
                    ['sbaeuc_proj@' lib], ['sbaeuc_projac@' lib], 150, 'MotStr', prob.qr0, prob.cal);
  sbatest_assert(ret == ret0 && isequal(popt, popt0), 'reftype is case-sensitive');

  % A column p0 gives a column popt with the same values.
  [ret, popt, info] = sbatest_run(prob, 'p0', prob.p0');
  sbatest_assert(ret == ret0 && iscolumn(popt) && isequal(popt', popt0) && isequal(info, info0), ...
                 'column p0: popt %s, or other values', mat2str(size(popt)));
  % ...and the .m callbacks receive aj and bi in p0's orientation.
  [ret, popt] = sbatest_run(prob, 'p0', prob.p0', 'callbacks', 'm', 'itmax', 1);
  [retr, poptr] = sbatest_run(prob, 'callbacks', 'm', 'itmax', 1);
  sbatest_assert(ret == 1 && retr == 1 && isequal(popt', poptr), 'column p0 with .m callbacks differs');

  % mcon, ncon: the first cameras / points keep their values.
  [ret, popt] = sbatest_run(prob, 'mcon', 2, 'ncon', 10);
  sbatest_assert(ret > 0 && isequal(popt(1:12), prob.p0(1:12)) && ...
                 isequal(popt(43:72), prob.p0(43:72)) && ~isequal(popt(13:18), prob.p0(13:18)), ...
                 'mcon/ncon did not hold the first cameras/points');

  % verbose prints the eucsbademo summary lines through the host.
  out = evalc('[ret, popt, info] = sbatest_run(prob, ''verbose'', 1);');
  sbatest_assert(ret == ret0, 'verbose changed the result');
  expected = {'SBA using 465 3D pts, 7 frames and 1916 image projections, 1437 variables', ...
              sprintf('SBA returned %d in %d iter, reason %d, error %g [initial %g]', ret0, ...
                      info0(6), info0(7), info0(2) / prob.nvis, info0(1) / prob.nvis), ...
              'Elapsed time: '};
  for k = 1:numel(expected)
    sbatest_assert(~isempty(strfind(out, expected{k})), 'verbose output lacks "%s":\n%s', expected{k}, out);
  end
  printf('verbose output:\n%s', out);

  % The solver is sba 1.6's chol, named, not auto (the extension drivers' default, which says
  % what it chose when verbose), unless SBA_LINSOLVER names one: auto, say.
  sbatest_assert(isempty(strfind(out, 'linear solver auto')), 'the default solver is auto:\n%s', out);
  old = getenv('SBA_LINSOLVER');
  setenv('SBA_LINSOLVER', 'auto');
  restore = onCleanup(@() setenv('SBA_LINSOLVER', old));
  out = evalc('[ret, popt, info] = sbatest_run(prob, ''verbose'', 1);');
  sbatest_assert(ret == ret0 && isequal(popt, popt0), 'SBA_LINSOLVER=auto: not chol''s result');
  sbatest_assert(~isempty(strfind(out, 'sba_motstr_levmar: linear solver auto: chol (S of 42 unknowns')), ...
                 'SBA_LINSOLVER=auto: no line saying what auto chose:\n%s', out);
  setenv('SBA_LINSOLVER', 'nonsense');
  out = evalc('[ret, popt] = sbatest_run(prob);');
  sbatest_assert(ret == ret0 && isequal(popt, popt0), 'SBA_LINSOLVER=nonsense: not chol''s result');
  sbatest_assert(~isempty(strfind(out, 'unknown SBA_LINSOLVER "nonsense"')) && ...
                 ~isempty(strfind(out, '); using chol')), 'SBA_LINSOLVER=nonsense: not said:\n%s', out);
  clear restore;

  % 'strategy=trust-region', just before or just after reftype: the same minimum in fewer
  % iterations; 'strategy=sba' is the default; an unknown name is an argument error.
  args = {prob.n, 0, prob.m, 0, prob.vmask, prob.p0, 6, 3, prob.x, 2, ['sbaeuc_proj@' lib], ...
          ['sbaeuc_projac@' lib], 150, 0, [1e-3 1e-12 1e-12 1e-12 0]};
  [rt, pt, it] = sba(args{:}, 'motstr', 'strategy=trust-region', prob.qr0, prob.cal);
  [rt2, pt2, it2] = sba(args{:}, 'strategy=trust-region', 'motstr', prob.qr0, prob.cal);
  [rt3, pt3] = sba(args{:}, 'strategy=trust-region', prob.qr0, prob.cal);
  printf('strategy=trust-region: %d iterations (sba: %d), error %.9g (sba: %.9g)\n', rt, ret0, ...
         it(2) / prob.nvis, info0(2) / prob.nvis);
  sbatest_assert(rt > 0 && rt < ret0 && it(7) == 4 && abs(it(2) / info0(2) - 1) < 1e-6, ...
                 'strategy=trust-region: %d iterations, reason %d, error %.12g (sba: %d, %.12g)', ...
                 rt, it(7), it(2), ret0, info0(2));
  sbatest_assert(rt2 == rt && isequal(pt2, pt) && isequal(it2, it) && rt3 == rt && isequal(pt3, pt), ...
                 'the place of strategy= changed the result');
  [rs, ps, is] = sba(args{:}, 'strategy=sba', 'motstr', prob.qr0, prob.cal);
  sbatest_assert(rs == ret0 && isequal(ps, popt0) && isequal(is, info0), 'strategy=sba is not the default');
  try
    sba(args{:}, 'motstr', 'strategy=fast', prob.qr0, prob.cal);
    sbatest_assert(false, 'strategy=fast was accepted');
  catch err
    sbatest_assert(strcmp(err.identifier, 'sba:unknownStrategy') && ...
                   ~isempty(strfind(err.message, ['unknown strategy ''fast'' ' ...
                                                  '(expected one of: sba sba-clean-retry trust-region)'])), ...
                   'strategy=fast: %s (%s)', err.message, err.identifier);
  end

  % itmax 0: the Jacobian check, no iteration.
  evalc('[ret, popt, info] = sbatest_run(prob, ''itmax'', 0);');
  sbatest_assert(ret == 0 && isequal(popt, prob.p0) && info(1) == info(2), 'itmax 0 iterated');
end

function r = ifelse(c, a, b)
  if c
    r = a;
  else
    r = b;
  end
end
% SPDX-License-Identifier: BSD-3-Clause
