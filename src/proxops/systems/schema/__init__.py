"""The scenario schema of each built-in system (``proxops.systems.schema.<module>``): its pydantic
``Scenario`` model and sections, registered with
:func:`proxops.scenarios.registry.register_scenario`. Validation imports only these (pydantic and
light proxops modules); the system modules (``proxops.systems.<module>``) build and run."""
