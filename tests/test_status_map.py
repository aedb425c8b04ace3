"""The controller_status_t -> Run mapping is an explicit table
(wire/codec.py): every Run field a controller, estimator or timing source
produces is either carried by the status under the same name or listed as not
carried with where it comes from; every carried name exists on both sides."""

import sc_rt_lcm

from sc_rt.results.record.run import FIELDS
from sc_rt.wire import codec


def test_every_controller_sourced_field_is_carried_or_listed():
    carried = codec.STATUS_RUN_FIELDS + codec.STATUS_NAV_FIELDS + codec.STATUS_TIMING_FIELDS
    sourced = {f.name for f in FIELDS if f.source in ("controller", "estimator", "timing")}
    assert len(set(carried)) == len(carried)
    assert not set(carried) & set(codec.STATUS_NOT_CARRIED)
    assert sourced == set(carried) | set(codec.STATUS_NOT_CARRIED), (
        "unmapped:", sourced - set(carried) - set(codec.STATUS_NOT_CARRIED),
        "not a run field:", (set(carried) | set(codec.STATUS_NOT_CARRIED)) - sourced)


def test_every_carried_name_is_a_status_field():
    slots = set(sc_rt_lcm.controller_status_t.__slots__)
    for name in codec.STATUS_RUN_FIELDS + codec.STATUS_NAV_FIELDS + codec.STATUS_TIMING_FIELDS:
        assert name in slots, name
