from common import *
from kgarment.design import load_design
pr = problem("reference"); body = body_of(pr); g = build_garment(pr, body); strips = build_clutches(pr, body, g)
ev = Evaluator.from_problem(pr, body=body, garment=g, strips=strips, device="cpu")
d = load_design("/tmp/research/ref_run", ev.n_faces)
t = time.time()
res, st = solve(ev, d, acts_all(3))
rows = analyse(ev, strips, d, res, st)
print(f"== reference-preset final ({time.time()-t:.0f}s)")
for r in rows:
    print("  {motion:13s} {clutch:13s} strainOFF={strain_off:+.4f} strainON={strain_on:+.5f} share={share:+.3f} T_on={T_on:7.2f}N T_single={T_single:7.2f}N dE={dE_all:.3f} conv={conv}".format(**r), flush=True)
json.dump(rows, open(OUT / "m4_ref.json", "w"), indent=1)
