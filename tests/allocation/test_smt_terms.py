"""The SMT encoding's term maker (``smt_allocator._Terms``, z3's C API) makes the terms z3's
Python functions make, with the same ids, when called and held alike: z3 numbers terms in the
order they are made, reuses the numbers of terms it frees (a solver keeps only its rewritten
form of most assertions, so the asserted term itself is freed when its last reference goes),
and its answers depend on those numbers."""

import z3

from mrta_drake.allocation.smt_allocator import _Terms


def _with_python_functions(ctx: z3.Context, solver: z3.Solver):
    on = [z3.Bool(f"on_{k}", ctx) for k in range(3)]
    t = [z3.Real(f"t_{k}", ctx) for k in range(3)]
    same = z3.Bool("same", ctx)
    for k in range(3):
        solver.add(z3.Implies(on[k], t[k] >= 10.5 * k))
        solver.add(z3.Or(z3.Not(on[k]), z3.Not(on[(k + 1) % 3]), same))
    held = [z3.Not(z3.And(on[k], z3.BoolVal(k == 1, ctx))) for k in range(3)]
    solver.add(z3.Implies(z3.And(same, *held), t[0] >= t[1] + 3.25),
               z3.PbEq([(literal, 1) for literal in on], 1))
    held = [z3.Not(on[k]) for k in range(2)]
    solver.add(z3.Implies(on[0] == on[1], t[0] <= t[2]), z3.AtMost(*on, 2),
               z3.PbLe([(on[0], 3), (on[1], 4)], 5), z3.Or(*held, ctx))
    return [*on, *t, same]


def _with_terms(ctx: z3.Context, solver: z3.Solver):
    terms = _Terms(ctx)

    def add(*constraints):
        for k in range(len(constraints)):
            z3.Z3_solver_assert(terms.ref, solver.solver, constraints[k].ast)

    on = [terms.bool(f"on_{k}") for k in range(3)]
    t = [terms.real(f"t_{k}") for k in range(3)]
    same = terms.bool("same")
    for k in range(3):
        add(terms.implies(on[k], terms.at_least(t[k], 10.5 * k)))
        add(terms.any(terms.negation(on[k]), terms.negation(on[(k + 1) % 3]), same))
    held = [terms.negation(terms.all(on[k], terms.value(k == 1))) for k in range(3)]
    add(terms.implies(terms.all(same, *held), terms.at_least(t[0], terms.plus(t[1], 3.25))),
        terms.pb_equal([(literal, 1) for literal in on], 1))
    held = [terms.negation(on[k]) for k in range(2)]
    add(terms.implies(terms.equal(on[0], on[1]), terms.at_most(t[0], t[2])),
        terms.count_at_most(on, 2), terms.pb_at_most([(on[0], 3), (on[1], 4)], 5),
        terms.any(*held))
    return [*on, *t, same]


def _assertions(build):
    ctx = z3.Context()
    solver = z3.SimpleSolver(ctx=ctx)
    variables = build(ctx, solver)
    marker = z3.Bool("made_last", ctx)  # its id tells which ids are free at the end
    return ([(a.get_id(), a.sexpr()) for a in solver.assertions()],
            [v.get_id() for v in variables], marker.get_id())


def test_terms_match_z3s_python_functions():
    expected = _assertions(_with_python_functions)
    assert len(expected[0]) >= 10
    assert _assertions(_with_terms) == expected


def test_terms_answer_alike():
    answers = []
    for build in (_with_python_functions, _with_terms):
        ctx = z3.Context()
        solver = z3.SimpleSolver(ctx=ctx)
        variables = build(ctx, solver)
        assert solver.check() == z3.sat
        model = solver.model()
        answers.append([str(model.eval(v, True)) for v in variables])
    assert answers[0] == answers[1]
