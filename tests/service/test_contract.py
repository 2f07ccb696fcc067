"""The generated OpenAPI keeps every path and field that API.md makes binding."""

from service.main import create_app

PATHS = {
    "/health": "get",
    "/v1/presets": "get",
    "/v1/presets/{name}": "get",
    "/v1/analysis/rigidity": "post",
    "/v1/analysis/second-order": "post",
    "/v1/analysis/critical-points": "post",
    "/v1/analysis/configuration-space": "post",
    "/v1/analysis/splitting": "post",
    "/v1/design/splitting": "post",
    "/v1/analysis/critical-values": "post",
    "/v1/analysis/robustness": "post",
}
FIELDS = {
    "Health": ["status", "version"],
    "PresetInfo": ["name", "description", "parameters"],
    "RigidityResponse": ["rank", "expected_dof", "dof", "critical", "singular_values",
                         "zero_modes", "trivial_motions", "self_stresses", "projection_residual"],
    "SecondOrderResponse": ["kind", "self_stress", "zero_modes", "q", "q_eigenvalues",
                            "tangents", "reason"],
    "CriticalPointsResponse": ["critical_points", "near_misses", "search"],
    "CriticalPointOut": ["configuration", "kind", "self_stress", "q_eigenvalues", "tangents",
                         "residual"],
    "SpaceResponse": ["components", "critical_points", "segments"],
    "ComponentOut": ["closed", "through_start", "positions", "angles", "winding",
                     "critical_points"],
    "SegmentOut": ["from", "to", "component"],
    "SplittingResponse": ["branch_points"],
    "BranchSplitOut": ["index", "configuration", "delta", "shift", "sign", "connects"],
    "DesignResponse": ["feasible", "perturbation", "predicted", "conflicts", "verified"],
    "PredictedOut": ["branch_point", "sign", "delta"],
    "CriticalValuesResponse": ["curves", "regions"],
    "RegionOut": ["point", "components", "signature"],
    "RobustnessResponse": ["margin", "nearest", "critical_configuration"],
    "SpaceOptions": ["max_points", "strain_tol"],
    "CriticalValuesOptions": ["resolution"],
    "SplittingRequest": ["linkage", "perturbation"],
    "DesignRequest": ["linkage", "targets", "adjustable", "max_change"],
    "TargetIn": ["branch_point", "sign"],
    "CriticalValuesRequest": ["linkage", "axes", "options"],
    "AxisIn": ["bar", "min", "max"],
    "RobustnessRequest": ["linkage", "adjustable"],
    "Linkage": ["dimension", "vertices", "bars"],
    "Vertex": ["id", "position", "fixed"],
    "Bar": ["id", "ends", "length"],
    "Tolerances": ["rank_rtol", "residual_atol"],
}


def test_contract_paths_and_fields():
    spec = create_app().openapi()
    for path, method in PATHS.items():
        assert method in spec["paths"].get(path, {}), path
    schemas = spec["components"]["schemas"]
    for name, fields in FIELDS.items():
        variants = [k for k in schemas if k == name or k.startswith(name + "-")]
        assert variants, name
        props = set().union(*(schemas[k].get("properties", {}).keys() for k in variants))
        missing = [f for f in fields if f not in props]
        assert not missing, (name, missing)
