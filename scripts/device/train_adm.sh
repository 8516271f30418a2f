#!/bin/bash
# The ADM run of scripts/device/train.sh (kept under this name for the commands in docs/training.md).
TASK=adm exec bash "$(dirname "$0")/train.sh" "$@"
