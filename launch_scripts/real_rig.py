#!/usr/bin/env python3
"""The real rig: daq (NI-DAQmx, or a recorded file), analyzer, fitter and recorder until Ctrl-C.

.venv/bin/python launch_scripts/real_rig.py [--params-file FILE] [--processes]
[--set daq.force_channel=cDAQ1Mod1/ai0] [--set daq.backend=file
--set daq.file_path=session.csv]
"""

import sys

from fmm_ros.ros.launch import REAL_RIG, launch_main

if __name__ == '__main__':
    sys.exit(launch_main(REAL_RIG, __doc__.splitlines()[0]))
