#!/usr/bin/env python3
"""The simulated rig: hammer_sim, rig_sim, analyzer, fitter and recorder until Ctrl-C.

.venv/bin/python launch_scripts/sim_rig.py [--params-file FILE] [--processes]
[--set hammer_sim.rate_factor=20] [--set rig_sim.effects="['stribeck']"]
"""

import sys

from fmm_ros.ros.launch import SIMULATED_RIG, launch_main

if __name__ == '__main__':
    sys.exit(launch_main(SIMULATED_RIG, __doc__.splitlines()[0]))
