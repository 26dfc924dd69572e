"""The names of the simulator's built-in scenarios, without building them (or importing the simulator).

`simulator.scenarios` builds vessels, sea states and sensor models (numpy, the MAVLink dialect): close to a
second of imports. The command line lists the names in ``--help`` and as argparse choices, and must not pay
for that; here, not in `simulator`, because importing that package decides first whether the compiled hot
path is used (`wire.compiled`, which a help page need not load). A test holds this tuple equal to the keys
of `simulator.scenarios.SCENARIOS`.
"""

SCENARIO_NAMES: tuple[str, ...] = (
    "fossen_strand_1999",
    "torsetnes_2004",
    "torsetnes_2004_mast",
    "snijders_2005",
    "hassani",
    "hassani_sea_change",
    "hajivand_2010",
    "mss_osv",
    "mss_supply_storm",
    "mss_supply_wind",
)
