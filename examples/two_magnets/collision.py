"""One off-centre collision of two spherical magnets (Bartz & Shaw), in the paper's units.

R = 6.94, m = 1, k = 1, Gamma = 0.05 (dashpot c = 0.1), 3 mu0 m1 m2 / 4 pi = 1; the spheres start
300 apart with speed 5.78e-3 each, impact parameter b = 4 R, dipoles along the line of centres.
Prints the final spin against v b / (beta R^2) with beta = 14/5 and the conservation figures.
"""
import argparse
import time

import numpy as np

import demkit as dk

R, V = dk.two_magnets.PAPER_RADIUS, dk.two_magnets.PAPER_SPEED


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--b-over-r", type=float, default=4.0, help="impact parameter b/R")
    parser.add_argument("--dt", type=float, default=0.01, help="Euler-Cromer time step")
    args = parser.parse_args(argv)

    scene = dk.two_magnets.TwoMagnets(b_over_R=args.b_over_r).scene()
    e0, l0 = scene.energy(), scene.angular_momentum()
    print(f"two magnets: b/R = {args.b_over_r}, v = {V}, R = {R}; U/K at the start = "
          f"{e0['magnetic'] / e0['kinetic']:.1e}", flush=True)
    predicted = V * args.b_over_r * R / (14 / 5 * R**2)
    duration = 32000 + 6 * 2 * np.pi / predicted
    start = time.perf_counter()
    traj = dk.Simulation(scene, dk.EulerCromer(dt=args.dt)).run(duration=duration, record_every=1.0)
    elapsed = time.perf_counter() - start
    steps = round(duration / args.dt)
    print(f"ran {steps:,} Euler-Cromer steps (dt = {args.dt}) in {elapsed:.2f} s "
          f"({steps / elapsed / 1e6:.1f} million steps/s, compilation included)")

    outcome = dk.two_magnets.outcome(traj)
    print(f"outcome: {outcome}")
    if outcome == "stick":
        omega, sigma = dk.two_magnets.final_spin(traj, revolutions=5)
        beta = V * args.b_over_r * R / (omega * R**2)
        print(f"final spin  omega_f = {omega:.6e} +- {sigma:.1e}  (mean of 5 revolutions)")
        print(f"predicted   v b/(beta R^2) = {predicted:.6e}  with beta = 14/5")
        print(f"measured beta = v b/(omega_f R^2) = {beta:.4f}   (14/5 = 2.8; central force: 2)")
        si = dk.units.paper_magnets()
        print(f"for the paper's 5 mm NdFeB magnets: omega_f = {si.to_si(omega, 'angular_velocity'):.0f} rad/s "
              f"= {si.to_si(omega, 'angular_velocity') / (2 * np.pi):.1f} rev/s")

    L, P = traj.angular_momentum, traj.linear_momentum()
    e = traj.energy
    balance = e["total"] + e["dissipated"]
    print("conservation over the run:")
    print(f"  angular momentum  max |L - L0| / |L0| = {np.abs(L - l0).max() / np.linalg.norm(l0):.1e}")
    print(f"  linear momentum   max |P - P0| / sum m|v| = "
          f"{np.abs(P - P[0]).max() / (2 * V):.1e}")
    print(f"  energy            total + dissipated drifts by "
          f"{np.abs(balance - balance[0]).max() / np.abs(e['magnetic']).max():.1e} of max |U_magnetic| "
          f"(first order in dt)")
    print(f"  dissipated {e['dissipated'][-1]:.3e}; final total energy {e['total'][-1]:.3e} "
          f"(initial {e['total'][0]:.3e})")
    return traj


if __name__ == "__main__":
    main()
