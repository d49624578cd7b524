# Boots the board and lists its devices: the quickest check that it works.
. "$(dirname "$0")/lib.sh"
vm_ctl_open
gpio_sim_setup
unbind_fbcon
ls -l /dev/video* /dev/fb* /dev/gpiochip* /dev/sd* 2>&1
gpiodetect; gpioinfo propcam-buttons
v4l2-ctl -D -d /dev/video0 | head -5
vm note hello from the guest
vm shot smoke
