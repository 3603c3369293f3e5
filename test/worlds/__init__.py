"""An independent generator of friction-rig lab data: continuous physics, a DAQ, damage, truth.

Nothing here imports the product (a test holds it to that) or shares its methods: the plant
is driven by the continuous hammer force with stick-slip events located in continuous time
(closed-form half cycles or DOP853 with events, never a per-sample step), hits are analytic
pulses with exact impulses, and the signals pass through oversampled analog filters, hum,
drift, noise and an ADC before anyone sees a sample. See README.md in this folder.

Modules: `friction` (laws), `world` (plant and effects), `pulses` (hammer hits), `motion`
(the stick-slip solver), `daq` (the acquisition chain), `damage`, `lab` (sessions, records,
truth), `csvfile` (the per-impact CSV), `speed` (the timing script).

Speed (process CPU time on a shared 2-core machine, `python -m worlds.speed` from test/): the
rig's motion over a 33 s record costs 2.5 ms on the closed-form path, 19 ms forced through
DOP853 (the general path) and 57 ms for a Stribeck plus cubic-stiffness world, which has no
closed form. A whole 33 s record with the default DAQ chain (80 kHz filtering of the ~3 s of
motion, hum, drift, noise and a 16-bit ADC on 330,000 samples per channel) costs about 41 ms
on the closed-form path and 85 ms on the general one; a 20-hit session (~12 minutes of signal)
about 0.75 s.
"""

from worlds.csvfile import write_record_csv
from worlds.damage import (
    Damage,
    DeadVibrometer,
    DoubleHit,
    DroppedSamples,
    ForceClip,
    NonFiniteBurst,
    VibrometerSaturation,
    random_damage,
)
from worlds.daq import (
    AnalogChannel,
    AnalogFilter,
    ChannelChain,
    ContinuousSignal,
    DaqChain,
    DiscreteFilter,
    HumComponent,
    analog_channel,
    digitise,
)
from worlds.friction import (
    AsymmetricCoulomb,
    Coulomb,
    DwellStrengthening,
    FrictionLaw,
    SpeedRegimes,
    StaticFriction,
    Stribeck,
    WearPatch,
    WearTrack,
)
from worlds.lab import (
    HitTruth,
    LabRecord,
    RunIn,
    Session,
    Truth,
    impact_record,
    record_session,
)
from worlds.motion import MotionEvent, PlantState, Trajectory, linear_response, simulate_motion
from worlds.pulses import HalfSine, PlacedPulse, Pulse, SkewedPulse, random_pulse
from worlds.world import (
    FMM_PLANT,
    CubicStiffness,
    Plant,
    SecondMode,
    VelocityOffset,
    VibrometerLag,
    ViscousDamping,
    World,
)

__all__ = [
    'FMM_PLANT',
    'AnalogChannel',
    'AnalogFilter',
    'AsymmetricCoulomb',
    'ChannelChain',
    'ContinuousSignal',
    'Coulomb',
    'CubicStiffness',
    'DaqChain',
    'Damage',
    'DeadVibrometer',
    'DiscreteFilter',
    'DoubleHit',
    'DroppedSamples',
    'DwellStrengthening',
    'ForceClip',
    'FrictionLaw',
    'HalfSine',
    'HitTruth',
    'HumComponent',
    'LabRecord',
    'MotionEvent',
    'NonFiniteBurst',
    'PlacedPulse',
    'Plant',
    'PlantState',
    'Pulse',
    'RunIn',
    'SecondMode',
    'Session',
    'SkewedPulse',
    'SpeedRegimes',
    'StaticFriction',
    'Stribeck',
    'Trajectory',
    'Truth',
    'VelocityOffset',
    'VibrometerLag',
    'VibrometerSaturation',
    'ViscousDamping',
    'WearPatch',
    'WearTrack',
    'World',
    'analog_channel',
    'digitise',
    'impact_record',
    'linear_response',
    'random_damage',
    'random_pulse',
    'record_session',
    'simulate_motion',
    'write_record_csv',
]
