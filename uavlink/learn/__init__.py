"""Learning from teachers: ``training`` (PPO with SB3, the warm start), ``imitation`` (behaviour
cloning of a teacher), ``teachers`` (the aoa rule's variants, a fleet's solo teacher,
``make_teacher``), ``lead_teacher`` (a fleet's lead teacher), ``policy_transfer`` (a start from
another policy's weights), ``selection`` (the best weights on validation episodes),
``privileged`` (the privileged critic's training-only columns) and ``shadow_estimation`` (the
GPS-free shadowing estimate a teacher's gate reads). Layer: above ``policies``, beside
``evaluation`` (neither imports the other).

May import: ``config``, ``errors``, ``seeding``, ``radio``, ``mobility``, ``env``, ``rollout``,
``policies``. Torch and stable-baselines3 are imported inside the functions that need them (in
``training``, ``imitation``, ``policy_transfer``, ``selection``, ``monitor`` and ``snapshot``), and by
``privileged`` when it is imported (which only ``training`` does, inside a function): importing
any other module of the package loads neither.
"""
