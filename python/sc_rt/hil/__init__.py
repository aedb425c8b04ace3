"""HIL orchestration (``sc-rt hil``, ``sc-rt floor``): starting the controller, the emulator and the
logger, and the bench's floor."""
