"""The only place that converts between HTTP schemas and engine types, one module per resource:
:mod:`.common` (linkages, tolerances, vectors), :mod:`.analysis`, :mod:`.presets`, :mod:`.space`,
:mod:`.design` (splitting, design, robustness, maps) and :mod:`.jobs` (jobs and sweeps)."""

from service.mappers.analysis import rigidity_out, second_order_out
from service.mappers.common import (
    DEFAULT_MARGIN,
    bar_values,
    linkage_in,
    linkage_out,
    packed_array,
    positions_out,
    problem_in,
    tolerances_out,
    vertex_vectors,
)
from service.mappers.design import (
    SliceOptions,
    critical_values_in,
    critical_values_out,
    design_in,
    design_margin,
    design_out,
    robustness_in,
    robustness_out,
    splitting_out,
)
from service.mappers.jobs import (
    SWEEP_CSV_COLUMNS,
    SweepJob,
    job_body_in,
    job_out,
    job_summary_out,
    sweep_csv,
    sweep_in,
    sweep_out,
)
from service.mappers.presets import (
    parameter_description,
    parameter_schema,
    preset_overrides_in,
    presets_out,
)
from service.mappers.space import (
    critical_list_out,
    critical_points_out,
    space_options_in,
    space_out,
)

__all__ = [
    "DEFAULT_MARGIN",
    "SWEEP_CSV_COLUMNS",
    "SliceOptions",
    "SweepJob",
    "bar_values",
    "critical_list_out",
    "critical_points_out",
    "critical_values_in",
    "critical_values_out",
    "design_in",
    "design_margin",
    "design_out",
    "job_body_in",
    "job_out",
    "job_summary_out",
    "linkage_in",
    "linkage_out",
    "packed_array",
    "positions_out",
    "parameter_description",
    "parameter_schema",
    "preset_overrides_in",
    "presets_out",
    "problem_in",
    "rigidity_out",
    "robustness_in",
    "robustness_out",
    "second_order_out",
    "space_options_in",
    "space_out",
    "splitting_out",
    "sweep_csv",
    "sweep_in",
    "sweep_out",
    "tolerances_out",
    "vertex_vectors",
]
