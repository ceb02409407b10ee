#!/usr/bin/env bash
# Redraw the README's animation of every shipped scene into docs/figures/ (needs the viz
# extra: pip install '.[viz]'). 320x240 at 10 fps keeps each GIF at a few hundred KB at most.
set -euo pipefail
cd "$(dirname "$0")/.."
render() { hecker-dynamics render "$1" -o "docs/figures/$1.gif" --overwrite --fps 10 --size 320x240 "${@:2}"; }
render sample --trail left/hook --contacts
render seesaw --trail load
render door --trail door/handle --contacts
render gears --trail bar --contacts
render car_flip --trail car --contacts
render ship --trail ship
render chain --trail link49
render bridge --trail crate_b --contacts
render ragdoll --trail head --contacts
render robot --trail robot --contacts
render kiwi --trail kiwi --contacts
render warehouse --trail crate --contacts
