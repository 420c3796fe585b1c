"""Defaults the stages share with the command line.

They live in a module that imports nothing, so that ``twin --help`` and a
command's argument errors answer at once: the parser reads its defaults here,
and the stages that use them import them from here (and name them in their own
namespace, e.g. :data:`twin.loop.bootstrap.DEFAULT_RECORDS`).

Examples
--------
>>> from twin.defaults import DEFAULT_RECORDS, DEMO_RECORDS
>>> DEMO_RECORDS < DEFAULT_RECORDS
True
"""

#: The update's methods: its samplers (:data:`twin.update.SAMPLERS`, the default first), then the Laplace
#: approximation of the pole fit (:mod:`twin.update.laplace`).
METHODS = ("hmc", "gibbs", "paper", "laplace")

#: Every sampler's draws kept per chain and chains, by default (:class:`twin.update.SamplerOptions`).
DRAWS, CHAINS = 500, 4
#: HMC's warm-up iterations by default and at least (the step size and the metric are tuned there).
HMC_WARMUP, HMC_MIN_WARMUP = 250, 50
#: The Gibbs samplers' burn-in sweeps by default.
GIBBS_BURN_IN = 20

#: Records the loop calibrates the sampler's posterior on when not told otherwise (``bootstrap=None``):
#: the number every calibrated coverage figure was measured with (docs/decisions/loop-calibration.md). About 2 min on
#: 2 cores for 20-min records at 256 Hz.
DEFAULT_RECORDS = 12
#: A determined parameter seen on at least one but fewer than :data:`twin.loop.pooling.MIN_RECORDS` records is seen on
#: more: further batches of ``records`` are simulated, up to this many batches in all
#: (:func:`twin.loop.bootstrap.bootstrap_factors`).
MAX_BATCHES = 3

#: Jackknife samples per mode of an extraction (``twin extract``, the demo, the loop): 80 s blocks of a 20-min
#: record, longer than three time constants (about 3 x 25 s) of the hydro unit's slowest mode, so the sample
#: spread is honest for every mode. A shorter record, or a slower mode, needs fewer (the extraction says so).
SAMPLES = 15
#: Records the demo calibrates its last update on by default (the loop's is :data:`DEFAULT_RECORDS`): a third
#: of the loop's, so that ``twin demo`` runs in under a minute on 2 cores
#: (docs/decisions/demo-calibration-records.md).
DEMO_RECORDS = 4

#: A simulated record by default: its length [s], its sampling rate [Hz] (the FMU's communication step is its
#: inverse) and the sensor noise's std as a fraction of the median channel RMS.
RECORD_DURATION_S = 1200.0
SAMPLING_RATE_HZ = 256.0
NOISE_RATIO = 0.05

#: The highest frequency the demo's and the sweep's extraction look for modes up to [Hz]: the hydro unit's
#: lightly damped modes below it; a faster machine needs more (``--fmax``).
DEMO_FMAX_HZ = 60.0

#: A mode of the extraction is the average of its poles at this many model orders (at most).
ORDERS_PER_MODE = 8
#: The largest model order an extraction's stabilisation diagram reaches.
MAX_ORDER = 100
#: The extraction's identification algorithms (:mod:`twin.extract.algorithms`), the default first: covariance-driven
#: SSI, and pLSCF for heavily damped, overlapping modes.
ALGORITHMS = ("ssi", "plscf")

#: Samples per mode of a synthetic modes file (``twin synth``, :func:`twin.update.synthesize_modes`).
SYNTHETIC_SAMPLES = 100

#: Rounds of diagnose, add, update that the loop runs at most.
MAX_ROUNDS = 4

#: Days from a tracker's first record over which it learns the laws and sets its chart; no alarm in them.
BASELINE_DAYS = 14.0
#: The false-alarm rate [alarms per unit-year] a tracker's control limit is set for.
FALSE_ALARMS_PER_YEAR = 0.1
