//! End-to-end tests of harvemu; the tests live in `tests/tests/`, one file per concern.
