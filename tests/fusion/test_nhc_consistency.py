"""The NHC vehicle states (IMU mount pitch and yaw in the car, IMU -> rear-axle lever) have
σ that can be believed, and where a drive cannot see one the run says so.

Monte Carlo over simulated cars (``tests/nhc_cars.py``: a random lever 0.5–2 m ahead of and
0.3–1 m above the axle, a random 1° mount, an industrial IMU, a drive of flat turns, speed
changes and hills; the constraint exact at the axle, the filter's NHC σ 0.02 m/s). Oracle:
the normalised estimation error squared of the observed states over the cars is inside the
χ² interval of its degrees of freedom; the lever's lateral and vertical components, which
flat turns do not show (no roll rate), keep more than half their prior σ and are flagged
not observable instead of being printed as measured."""
import numpy as np
from scipy.stats import chi2

import nhc_cars


def test_vehicle_states_nees_in_band_and_unobservable_flagged():
    e, flags = [], []
    for seed in range(4):
        (ne, _), res = nhc_cars.run_car(seed, nhc_sigma=(0.02, 0.02), loops=3)
        i = res.init
        flags.append([i["vehicle_mount_observable"][0], i["vehicle_mount_observable"][2], *i["nhc_lever_observable"]])
        e.append(ne)
    e, flags = np.array(e), np.array(flags)
    # observed: mount pitch and yaw, the forward lever; not observed: lateral and vertical lever
    assert flags[:, [0, 1, 3]].all() and not flags[:, [2, 4]].any(), flags
    obs = e[:, [0, 1, 3]]
    dof = obs.size
    nees = float(np.sum(obs ** 2))
    assert chi2.ppf(0.001, dof) <= nees <= chi2.ppf(0.999, dof), (nees, dof, obs)
