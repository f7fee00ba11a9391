// The paper's rig: one tendon, one stepper (Uno + TB6600), one load cell (Mega, A0). Hand-written with the
// values of helpers/hardware.py; the contract is in rig_config.h. RIG_HASH is a placeholder until the header
// is generated from the rig file (python -m helpers.rigfile.firmware_header RIGFILE -o OUT.h).
#ifndef RIG_CONFIG_PAPER_H
#define RIG_CONFIG_PAPER_H

#define RIG_HASH "00000000"
#define RIG_NAME "paper"
#define RIG_AXES 1
#define RIG_CHANNELS 1
#define RIG_MIN_INTERVAL_US 639        // 400 mm/s at 0.25525 mm/step
#define RIG_MAX_INTERVAL_US 1000000L   // one step per second; slower is a dwell
#define RIG_AXIS_TRAVEL_STEPS {156}    // 40 mm at 0.25525 mm/step
#define RIG_PROGRAMME_MAX 64
#define RIG_DAQ_RATE_MIN_HZ 100
#define RIG_DAQ_RATE_MAX_HZ 2000
#define RIG_DAQ_RATE_DEFAULT_HZ 1000
#define RIG_DAQ_BAUD 500000L
#define RIG_STEPPER_BAUD 115200L
#define RIG_ADC_CLIP_LOW_COUNTS 116    // 3.8 mA through 150 ohm (helpers.hardware.CLIP_LOW_COUNTS)
#define RIG_ADC_CLIP_HIGH_COUNTS 628   // 20.5 mA less a 2-count margin (helpers.hardware.CLIP_HIGH_COUNTS)

#endif
