"""The `multirotor` package's airframes as the peer flies them (imported by
scripts/peer-multirotor.py and scripts/spec-priors.py).

- **Tarot T18**: the package's own `models/tarott18.py` (mass, rotors, propeller k_thrust and
  k_drag, motor R, k_emf), its propellers given the motor that file leaves commented out.
- **DJI Mavic Pro**: the package's `models/djimavicpro.py` is one comment line in 0.5.0 (and
  0.4.4, and its GitHub head): a link to the model it was to be built from,
  souhaiel1/DJI-Mavic-pro-simplified-modelling-and-simulation. The harness builds it with the
  package's own classes (`MotorParams`, `PropellerParams`, `VehicleParams`, `Motor`) from that
  source's figures: 0.743 kg, four rotors, a 3S pack of 3830 mAh, motors of 1400 rpm/V (its
  Calculations.xlsx: 798 rpm at 0.57 V), a body of 0.0197 m² at C_D 1.0. What the source
  does not give is the harness's ASSUMPTION, stated here: DJI's 8330 propeller (0.2108 m) with
  static C_T 0.11 and C_P 0.045 ((n, D) convention; the range UIUC measured for 8-inch
  APC-type propellers, a figure of merit of 0.65) and a winding resistance of 0.20 Ω (an
  1806-size 1400 KV motor).

Each motor's current is the package's `Motor.step` (I = (V − k_e·ω)/R) at the speed that
gives the thrust, the pack's from its duty-cycle average: the electrical power is the
package's, not dronewatt's.
"""
import copy
import math

RHO, G = 1.225, 9.81


class Airframe:
    """One airframe: its facts, its pack, its body drag and the package's motors."""

    def __init__(self, key, name, mass, props, prop_m, mp, k_thrust, k_drag, vmax, sim, cells, mah, cda,
                 cda_source, chemistry="lipo"):
        from multirotor.simulation import Motor
        self.key, self.name, self.mass, self.n, self.prop_m = key, name, mass, props, prop_m
        self.k_thrust, self.k_drag, self.vmax = k_thrust, k_drag, vmax
        self.cells, self.mah, self.cda, self.cda_source, self.chemistry = cells, mah, cda, cda_source, chemistry
        mp = copy.deepcopy(mp)
        mp.k_drag = k_drag
        self.mp = mp
        self.motors = [Motor(copy.deepcopy(mp), sim) for _ in range(self.n)]

    def power_w(self, thrust_n):
        """Electrical power for a total thrust, W: each motor's current from the package."""
        t = max(thrust_n, 0.0) / self.n
        omega = math.sqrt(t / self.k_thrust)
        volts = omega * self.mp.k_emf + self.k_drag * omega ** 2 / self.mp.k_torque * self.mp.resistance
        total = 0.0
        for m in self.motors:
            m.speed = omega
            m.step(volts / self.mp.speed_voltage_scaling, max_voltage=self.vmax)
            total += m.current_average(self.vmax) * self.vmax
        return total

    def hover_w(self):
        """The motors' power in a hover (no avionics), W."""
        return self.power_w(self.mass * G)

    def figure_of_merit(self):
        """The propellers' figure of merit in this airframe's hover: ideal power over shaft power."""
        t = self.mass * G / self.n
        omega = math.sqrt(t / self.k_thrust)
        ideal = t ** 1.5 / math.sqrt(2 * RHO * math.pi * self.prop_m ** 2 / 4)
        return ideal / (self.k_drag * omega ** 3)

    def motor_efficiency(self):
        """Shaft power over electrical power in this airframe's hover."""
        t = self.mass * G / self.n
        omega = math.sqrt(t / self.k_thrust)
        return self.k_drag * omega ** 3 / (self.hover_w() / self.n)


def t18_layout():
    """The package's T18 as laid out (its VehicleParams): whether the octocopter's disks are
    coaxial or overlap (which would make the spec sheet's disk area, rotors × πD²/4, too
    large and the peer's η_h look too good), and its propellers' torque per thrust, m (the
    package's k_drag / k_thrust; C_P·D / (2π·C_T) in the (n, D) convention), against what a
    figure of merit of 0.65 gives at its hover's thrust coefficient."""
    import numpy as np
    from multirotor.models.tarott18 import VP, PP
    xy = np.array([[r * math.cos(t), r * math.sin(t)] for r, t in zip(VP.distances, VP.angles)])
    gaps = [float(np.linalg.norm(xy[i] - xy[(i + 1) % len(xy)])) for i in range(len(xy))]
    d = 0.4572
    t = VP.mass * G / len(VP.propellers)
    n = math.sqrt(t / PP.k_thrust) / (2 * math.pi)
    ct = t / (RHO * n * n * d ** 4)
    # in the (n, D) convention the figure of merit is C_T^1.5 / (√(π/2)·C_P)
    cp_at_065 = ct ** 1.5 / (math.sqrt(math.pi / 2) * 0.65)
    return dict(arms=len(VP.propellers), arm_m=float(VP.distances[0]), coaxial=False,
                motor_spacing_m=round(min(gaps), 3), disk_gap_m=round(min(gaps) - d, 3),
                torque_per_thrust_m=round(PP.k_drag / PP.k_thrust, 4),
                torque_per_thrust_at_fm_065_m=round(cp_at_065 * d / (2 * math.pi * ct), 4))


def t18():
    from multirotor.models.tarott18 import MP, PP, VP, BP, SP
    return Airframe("t18", "Tarot T18 (multirotor peer)", VP.mass, len(VP.propellers), 0.4572, MP, PP.k_thrust,
                    PP.k_drag, BP.max_voltage, SP, 6, 22000.0, 0.20,
                    "the harness's ASSUMPTION (the package models no body drag)")


MAVIC_CT, MAVIC_CP, MAVIC_R, MAVIC_KV, MAVIC_D = 0.11, 0.045, 0.20, 1400.0, 0.2108


def mavic():
    from multirotor.vehicle import MotorParams, SimulationParams
    k_e = 60.0 / (2 * math.pi * MAVIC_KV)
    mp = MotorParams(resistance=MAVIC_R, k_emf=k_e, moment_of_inertia=5e-6, max_current=20.0)
    # T = C_T ρ n² D⁴ and Q = C_P/(2π) ρ n² D⁵ with n = ω/2π
    k_thrust = MAVIC_CT * RHO * MAVIC_D ** 4 / (4 * math.pi ** 2)
    k_drag = MAVIC_CP / (2 * math.pi) * RHO * MAVIC_D ** 5 / (4 * math.pi ** 2)
    return Airframe("mavic", "DJI Mavic Pro (multirotor peer)", 0.743, 4, MAVIC_D, mp, k_thrust, k_drag, 13.05,
                    SimulationParams(dt=0.01, g=G), 3, 3830.0, 0.0197,
                    "souhaiel1's model, the package's cited source: 0.0197 m² at C_D 1.0")


AIRFRAMES = {"t18": t18, "mavic": mavic}
