"""tactilab.data_schemas: validated records shared by all parts, and file I/O at the edge.

Records are pydantic models in SI units; files at the edge carry units (``1.25mm``, ``20kPa``)
and are converted once. Import records from here::

    from tactilab.data_schemas import Scene, SensorArray, Protocol, load_example
"""

from tactilab.core import attach, package_version

#: public name -> module that defines it
_EXPORTS = {
    "Record": "base",
    "DisplayDescription": "display",
    "Stimulus": "stimulus",
    "Task": "experiment",
    "Protocol": "experiment",
    "ConstantStimuliConfig": "experiment_procedures",
    "StaircaseConfig": "experiment_procedures",
    "StaircaseTrack": "experiment_procedures",
    "PsiConfig": "experiment_procedures",
    "TrialRecord": "experiment_records",
    "Session": "experiment_records",
    "trials_to_dataframe": "experiment_records",
    "trials_from_dataframe": "experiment_records",
    "load_scene": "files",
    "list_examples": "files",
    "example_path": "files",
    "load_example": "files",
    "read_toml_record": "files",
    "read_json_record": "files",
    "SkinMaterial": "material",
    "PronyTerm": "material",
    "SkinLayer": "material",
    "ElasticBase": "material",
    "read_material": "files",
    "Recording": "recording",
    "read_recording": "recording_io",
    "read_recording_metadata": "recording_io",
    "write_recording": "recording_io",
    "recording_dataset": "recording_io",
    "Contact": "scene",
    "Scan": "scene",
    "Scene": "scene",
    "SensorArray": "sensors",
    "SensorGrid": "sensors",
    "FlatSurface": "surface",
    "SinusoidalGrating": "surface",
    "SquareWaveGrating": "surface",
    "IsolatedDefect": "surface",
    "HeightMap": "height_map_record",
    "RandomRoughSurface": "lab_surfaces",
    "MeasuredSurface": "lab_surfaces",
    "random_rough_surface": "rough_surface",
    "read_height_map": "height_map",
    "to_si": "units",
    "parse_hypothesis": "hypothesis",
}

#: names that moved to the ground floor (tactilab.core): they still resolve here, with a
#: DeprecationWarning, until 0.2.0
_MOVED = {name: "tactilab.core" for name in ("BatchReport", "batch_client", "read_result", "result_path",
                                             "run_batch", "stable_hash", "task_rng", "write_netcdf_atomic")}

__version__ = package_version()
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS, moved=_MOVED, removed_in="0.2.0")
